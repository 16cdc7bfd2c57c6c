//! Training end to end on three small synthetic materials: decreasing loss, resume identity,
//! export → latent.bin → the renderer's plain decoder, encode, and bad input (one-line errors,
//! exit code 2).

use crate::common::{error_line, make_data, material_nn, model_weights, path_str, small_config};
use material_nn::checkpoint::Checkpoint;
use material_nn::config::TrainConfig;
use material_nn::run::RunDir;
use material_nn::training::{train, Outcome, TrainRequest};
use renderer::formats::latent_file::LatentFile;
use renderer::formats::merl::{FILE_BYTES, HEADER_BYTES};
use std::path::Path;
use std::process::Command;
use std::sync::atomic::AtomicBool;

fn request(
    data: &Path,
    run: &Path,
    config: Option<TrainConfig>,
    resume: bool,
    stop: Option<u64>,
) -> TrainRequest {
    TrainRequest {
        data_dir: data.to_path_buf(),
        run_dir: run.to_path_buf(),
        config,
        resume,
        stop_after_steps: stop,
        table_cache_bytes: material_nn::training::DEFAULT_TABLE_CACHE_BYTES,
    }
}

#[test]
fn training_lowers_the_loss_and_exports_a_latent_file() {
    let dir = tempfile::tempdir().unwrap();
    let data = make_data(dir.path());
    let run = dir.path().join("run");
    let stop = AtomicBool::new(false);
    let outcome = train(
        &request(&data, &run, Some(small_config(40)), false, None),
        &stop,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(outcome, Outcome::Completed);
    let ckpt = Checkpoint::read(&RunDir(run.clone()).checkpoint()).unwrap();
    let h = &ckpt.state.history;
    assert_eq!(h.len(), 40);
    let first = h[0].train_loss;
    let last = h[h.len() - 1].train_loss;
    assert!(last < 0.9 * first, "training loss {first} -> {last}");
    assert!(h
        .iter()
        .all(|r| r.train_fre > 0.0 && r.validation.is_some()));
    for f in [
        "config.json",
        "split.json",
        "run.json",
        "reference.binary",
        "best.bin",
    ] {
        assert!(run.join(f).exists(), "{f}");
    }

    // Export through the command line; the renderer's plain decoder agrees with burn. Codes
    // are refined 40 steps here instead of 600 (the exports and evaluations below too): each
    // step costs as much as a training step, and 40 show the offset and residual fitted.
    let latent = dir.path().join("latent.bin");
    let out = material_nn(&[
        "export",
        "--run",
        path_str(&run),
        "--out",
        path_str(&latent),
        "--materials",
        "grey-clay,red-plastic",
        "--refine-steps",
        "40",
    ]);
    assert!(out.status.success(), "{out:?}");
    let file = LatentFile::read(&latent).unwrap();
    assert_eq!(file.latent_names(), vec!["grey-clay", "red-plastic"]);
    assert_eq!(file.training_materials.len(), 2);
    let trained = material_nn::inference::TrainedRun::load(&run).unwrap();
    // The exported code (z, its output offset and its residual, fitted by default) decodes to
    // the same net in burn and in the renderer's plain f32 forward pass.
    let code = file.latent("red-plastic").unwrap();
    assert_eq!(code.residual.len(), file.residual_len());
    assert!(code.residual.iter().any(|r| *r != 0.0));
    let x = renderer::brdf_coords::network_input_from_angles(0.3, 0.6, 1.1);
    let burn_y = trained.codec.predict(&code.z, code.offset, &code.residual, &x);
    let plain_y = file.decode(&code.z, code.offset, &code.residual).forward(&x);
    assert_ne!(plain_y, file.decode(&code.z, code.offset, &[]).forward(&x), "the residual counts");
    for c in 0..3 {
        assert!(
            (burn_y[c] - plain_y[c]).abs() < 1e-4 * burn_y[c].abs().max(1.0),
            "{burn_y:?} vs {plain_y:?}"
        );
    }

    // Exporting again from the latent file alone keeps its decoder and encodes its
    // materials again (here z alone: the codes differ from the first export's).
    let again = dir.path().join("again.bin");
    let out = material_nn(&[
        "export",
        "--model",
        path_str(&latent),
        "--data",
        path_str(&data),
        "--out",
        path_str(&again),
        "--refine-steps",
        "5",
        "--no-offset",
        "--no-residual",
    ]);
    assert!(out.status.success(), "{out:?}");
    let reexported = LatentFile::read(&again).unwrap();
    assert_eq!(reexported.latent_names(), file.latent_names());
    assert_eq!((&reexported.hypernetwork, &reexported.encoder, &reexported.f_ref), (&file.hypernetwork, &file.encoder, &file.f_ref));
    assert_eq!(reexported.training_materials, file.training_materials);
    assert!(reexported.latents.iter().all(|l| l.offset == [0.0; 3] && l.residual.is_empty()));
    assert!(file.latents.iter().any(|l| l.offset != [0.0; 3]), "the first export fitted offsets");

    // An interrupted export keeps its codes in OUT.partial/ and writes no OUT; the same
    // command continues from them (the kept code is marked here to show it is taken, not
    // made again) and ends with the uninterrupted export's codes; other settings start afresh.
    let resumed = dir.path().join("resumed.bin");
    let partial = material_nn::export::partial_dir(&resumed);
    let export_again = |steps: &str, extra: &[&str]| {
        let args = [&["export", "--model", path_str(&latent), "--data", path_str(&data), "--out", path_str(&resumed), "--refine-steps", steps, "--no-offset", "--no-residual"], extra].concat();
        material_nn(&args)
    };
    let out = export_again("5", &["--stop-after", "1"]);
    assert!(!out.status.success(), "an interrupted export fails: {out:?}");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("stopped after 1 of 2 codes") && stderr.lines().count() == 1, "{stderr}");
    assert!(!resumed.exists(), "no output before every code is made");
    let mut kept = LatentFile::read(partial.join("codes.bin")).unwrap();
    assert_eq!(kept.latents, reexported.latents[..1]);
    kept.latents[0].z[0] += 0.125;
    kept.write(partial.join("codes.bin")).unwrap();
    let out = export_again("5", &[]);
    assert!(out.status.success(), "{out:?}");
    assert!(String::from_utf8_lossy(&out.stdout).contains("1 of them from an interrupted export"), "{out:?}");
    let continued = LatentFile::read(&resumed).unwrap();
    assert_eq!(continued.latents[0], kept.latents[0], "the kept code is taken");
    assert_eq!(continued.latents[1..], reexported.latents[1..], "the rest as without the interruption");
    assert!(!partial.exists(), "the partial codes go once the file is written");
    assert!(!export_again("5", &["--stop-after", "1"]).status.success());
    let mut kept = LatentFile::read(partial.join("codes.bin")).unwrap();
    kept.latents[0].z[0] += 0.125;
    kept.write(partial.join("codes.bin")).unwrap();
    assert!(export_again("6", &[]).status.success());
    assert_ne!(LatentFile::read(&resumed).unwrap().latents[0], kept.latents[0], "codes of other settings are not taken");

    // Evaluation beside a briefly fitted NBRDF baseline, with tiny preview renders.
    let nbrdf = dir.path().join("nbrdf");
    let out = material_nn(&[
        "nbrdf-fit",
        "--data",
        path_str(&data),
        "--out",
        path_str(&nbrdf),
        "--epochs",
        "2",
        "--steps-per-epoch",
        "20",
    ]);
    assert!(out.status.success(), "{out:?}");
    let out = material_nn(&[
        "eval",
        "--run",
        path_str(&run),
        "--refine-steps",
        "40",
        "--split",
        "train",
        "--samples",
        "2000",
        "--pairs",
        "3",
        "--nbrdf",
        path_str(&nbrdf),
        "--resolution",
        "16x16",
        "--spp",
        "2",
        "--editing-images",
        "1",
    ]);
    assert!(out.status.success(), "{out:?}");
    // Editing rows of both models (NBRDF: its two networks' weights blended), the first pair
    // rendered against the blended table.
    let csv = std::fs::read_to_string(run.join("eval/editing.csv")).unwrap();
    let rows: Vec<Vec<&str>> = csv.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.iter().map(|r| r[0]).collect::<Vec<_>>(), ["frenbrdf", "nbrdf"].repeat(3), "{csv}");
    for (k, row) in rows.iter().enumerate() {
        let rendered = row[6].parse::<f64>().is_ok_and(f64::is_finite);
        assert_eq!(rendered, k < 2, "PSNR of the first pair only: {csv}");
    }
    assert_eq!(rows[0][1], rows[1][1], "the same pair for both models");
    assert_ne!(rows[0][3], rows[1][3], "{csv}");
    for model in ["table", "frenbrdf", "nbrdf"] {
        assert!(run.join(format!("eval/images/edit-0000-{model}.png")).is_file(), "{model}");
    }
    let csv = std::fs::read_to_string(run.join("eval/reconstruction.csv")).unwrap();
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let models: Vec<&str> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(column("model")).unwrap())
        .collect();
    assert_eq!(models, ["frenbrdf", "nbrdf", "frenbrdf", "nbrdf"], "{csv}");
    for line in csv.lines().skip(1) {
        let fields: Vec<&str> = line.split(',').collect();
        for c in ["rmse", "psnr", "ssim"] {
            let v: f64 = fields[column(c)].parse().unwrap();
            assert!(v.is_finite(), "{c} in {line}");
        }
    }
    let split: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(run.join("split.json")).unwrap()).unwrap();
    for name in split["train"].as_array().unwrap() {
        for model in ["table", "frenbrdf", "nbrdf"] {
            let png = run.join(format!(
                "eval/images/{}-{model}.png",
                name.as_str().unwrap()
            ));
            assert!(png.is_file(), "{}", png.display());
        }
    }
    let summary = std::fs::read_to_string(run.join("eval/summary.md")).unwrap();
    assert!(summary.contains("| frenbrdf | editing | 3 |") && summary.contains("| nbrdf | editing | 3 |"), "{summary}");
    assert!(
        summary.contains("| nbrdf | reconstruction | 2 |"),
        "{summary}"
    );

    // The tables' renders kept in a cache: the first evaluation with it gives the same
    // figures as without, the next one reads the kept renders instead of rendering.
    let cache = dir.path().join("table-renders");
    let eval_cached = |out: &str| {
        let out = dir.path().join(out);
        let status = material_nn(&[
            "eval", "--run", path_str(&run), "--refine-steps", "40", "--split", "train", "--samples", "2000", "--pairs", "0",
            "--resolution", "16x16", "--spp", "2", "--reference-cache", path_str(&cache), "--out", path_str(&out),
        ]);
        assert!(status.status.success(), "{status:?}");
        let csv = std::fs::read_to_string(out.join("reconstruction.csv")).unwrap();
        csv.lines().filter(|l| l.starts_with("frenbrdf,")).map(String::from).collect::<Vec<_>>()
    };
    let uncached: Vec<String> = csv.lines().filter(|l| l.starts_with("frenbrdf,")).map(String::from).collect();
    assert_eq!(eval_cached("cached-a"), uncached);
    let kept: Vec<_> = std::fs::read_dir(&cache).unwrap().map(|e| e.unwrap().path()).collect();
    assert_eq!(kept.len(), 2, "one render per material: {kept:?}");
    for path in &kept {
        renderer::formats::image_io::write_exr(path, 16, 16, &[renderer::Rgb::ZERO; 256]).unwrap();
    }
    assert_ne!(eval_cached("cached-b"), uncached, "the kept (blackened) renders were not read");

    // BRDF space only: no image columns.
    let out = material_nn(&[
        "eval",
        "--run",
        path_str(&run),
        "--refine-steps",
        "40",
        "--split",
        "train",
        "--samples",
        "500",
        "--pairs",
        "1",
        "--no-images",
    ]);
    assert!(out.status.success(), "{out:?}");
    let csv = std::fs::read_to_string(run.join("eval/reconstruction.csv")).unwrap();
    for line in csv.lines().skip(1) {
        let fields: Vec<&str> = line.split(',').collect();
        assert!(fields[6..9].iter().all(|f| f.is_empty()), "no image columns: {line}");
        // Albedo ratios (decoded over table at 0°, 45°, 75°, RGB) are measured all the same.
        assert_eq!(fields.len(), 18, "{line}");
        assert!(fields[9..].iter().all(|f| f.parse::<f64>().is_ok_and(|v| v > 0.0)), "{line}");
    }

    // The exported file evaluated without its run: the codes it carries are taken as they
    // are (the same rows whatever the refinement settings), the material it has none for
    // (rough-gold) is encoded with them; a file records no validation split.
    let eval_model = |steps: &str, out: &str| {
        let out = dir.path().join(out);
        let status = material_nn(&[
            "eval", "--model", path_str(&latent), "--data", path_str(&data), "--split", "all", "--out", path_str(&out),
            "--refine-steps", steps, "--samples", "500", "--pairs", "1", "--no-images",
        ]);
        assert!(status.status.success(), "{status:?}");
        let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
        assert!(summary.contains("2 of the 3 materials evaluated at the codes the latent file carries"), "{summary}");
        let csv = std::fs::read_to_string(out.join("reconstruction.csv")).unwrap();
        csv.lines().skip(1).map(String::from).collect::<Vec<_>>()
    };
    let (coarse, fine) = (eval_model("0", "model-eval-0"), eval_model("40", "model-eval-40"));
    assert_eq!(coarse.len(), 3, "{coarse:?}");
    for (a, b) in coarse.iter().zip(&fine) {
        assert!(a.starts_with("latent,"), "rows named for the file: {a}");
        assert_eq!(a == b, !a.contains("rough-gold"), "stored codes as they are, the rest encoded: {a} / {b}");
    }
    let out = material_nn(&[
        "eval", "--model", path_str(&latent), "--data", path_str(&data), "--split", "test", "--out", path_str(&dir.path().join("x")),
    ]);
    let line = error_line(&out);
    assert!(line.contains("latent.bin") && line.contains("training materials only"), "{line}");

    // Encode a sparse sample set and add it to the file.
    let csv = dir.path().join("sparse.csv");
    let mut text = String::from("theta_h,theta_d,phi_d,r,g,b\n");
    for i in 0..200 {
        let t = i as f32 / 200.0;
        text.push_str(&format!(
            "{},{},{},0.1,0.05,0.05\n",
            t * 1.5,
            (1.0 - t) * 1.5,
            t * 6.0
        ));
    }
    std::fs::write(&csv, text).unwrap();
    let out = material_nn(&[
        "encode",
        "--run",
        path_str(&run),
        "--samples",
        path_str(&csv),
        "--name",
        "sparse",
        "--add-to",
        path_str(&latent),
    ]);
    assert!(out.status.success(), "{out:?}");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["z"].as_array().unwrap().len(), 8);
    // 200 samples are a sparse set: refined for fewer steps than a table's code.
    assert_eq!(json["refine_steps"], serde_json::json!(material_nn::inference::SPARSE_REFINE_STEPS), "{json}");
    assert_eq!(LatentFile::read(&latent).unwrap().latents.len(), 3);

    // Encoding with the exported file alone (it carries the set encoder): a new library is
    // created from the model, a second code added; refinement lowers the fit error.
    let lib = dir.path().join("lib.bin");
    let out = material_nn(&[
        "encode",
        "--model",
        path_str(&latent),
        "--table",
        path_str(&data.join("grey-clay.binary")),
        "--name",
        "clay2",
        "--count",
        "4096",
        "--refine-steps",
        "30",
        "--add-to",
        path_str(&lib),
    ]);
    assert!(out.status.success(), "{out:?}");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let (before, after) = (json["loss_encoder"].as_f64().unwrap(), json["loss_refined"].as_f64().unwrap());
    assert!(after < before, "refinement {before} -> {after}");
    let library = LatentFile::read(&lib).unwrap();
    assert_eq!(library.latent_names(), vec!["clay2"]);
    // The output offset is fitted with z by default and stored with the code.
    let offset: Vec<f32> = json["offset"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap() as f32).collect();
    assert_eq!(library.latents[0].offset[..], offset[..]);
    assert!(offset.iter().any(|d| *d != 0.0), "{json}");
    // So is the residual.
    assert_eq!(json["residual_values"], serde_json::json!(file.residual_len()), "{json}");
    assert_eq!(library.latents[0].residual.len(), file.residual_len());
    assert_eq!(library.hypernetwork, file.hypernetwork);
    assert!(library.encoder.is_some());
    let out = material_nn(&[
        "encode",
        "--model",
        path_str(&latent),
        "--samples",
        path_str(&csv),
        "--name",
        "sparse2",
        "--refine-steps",
        "0",
        "--add-to",
        path_str(&lib),
    ]);
    assert!(out.status.success(), "{out:?}");
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(json["loss_encoder"], json["loss_refined"], "no refinement: {json}");
    assert_eq!(json["offset"], serde_json::json!([0.0, 0.0, 0.0]), "no refinement, no offset");
    assert_eq!(json["residual_values"], serde_json::json!(0), "no refinement, no residual");
    assert_eq!(LatentFile::read(&lib).unwrap().latent_names(), vec!["clay2", "sparse2"]);
    // Matching the latent fit's albedo needs a table: from one it moves the offset of the same
    // z; sparse samples are a one-line error.
    let clay = data.join("grey-clay.binary");
    let encode_clay = |extra: &[&str]| {
        let args = [&["encode", "--model", path_str(&latent), "--table", path_str(&clay), "--count", "4096", "--refine-steps", "10", "--no-residual"], extra].concat();
        let out = material_nn(&args);
        assert!(out.status.success(), "{out:?}");
        serde_json::from_slice::<serde_json::Value>(&out.stdout).unwrap()
    };
    let (plain, matched) = (encode_clay(&[]), encode_clay(&["--match-albedo"]));
    assert_eq!(plain["z"], matched["z"], "{plain} {matched}");
    assert_ne!(plain["offset"], matched["offset"], "{plain} {matched}");
    let out = material_nn(&["encode", "--model", path_str(&latent), "--samples", path_str(&csv), "--no-residual", "--match-albedo"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && stderr.contains("needs the material's table") && stderr.lines().count() == 1, "{stderr}");

    // Bad input to encode: one line naming the file, exit 2, the library untouched.
    let lib_bytes = std::fs::read(&lib).unwrap();
    let empty = dir.path().join("empty.csv");
    std::fs::write(&empty, "theta_h,theta_d,phi_d,r,g,b\n").unwrap();
    let nan = dir.path().join("nan.csv");
    std::fs::write(&nan, "0.1,0.2,0.3,0.5,NaN,0.5\n").unwrap();
    let mut no_encoder = LatentFile::read(&latent).unwrap();
    no_encoder.encoder = None;
    let old = dir.path().join("old.bin");
    no_encoder.write(&old).unwrap();
    let missing = dir.path().join("no-such-material.binary");
    let mut other = LatentFile::read(&latent).unwrap();
    other.hypernetwork[0].layers[0].weight[0] += 1.0;
    let foreign = dir.path().join("foreign.bin");
    other.write(&foreign).unwrap();
    let foreign_bytes = std::fs::read(&foreign).unwrap();
    for (model, input, add_to, expect) in [
        (&latent, ["--samples", path_str(&empty)], &lib, vec!["empty.csv", "no usable samples"]),
        (&latent, ["--samples", path_str(&nan)], &lib, vec!["nan.csv", "line 1"]),
        (&old, ["--samples", path_str(&csv)], &lib, vec!["old.bin", "no set encoder"]),
        (&latent, ["--table", path_str(&missing)], &lib, vec!["no-such-material.binary"]),
        (&latent, ["--samples", path_str(&csv)], &foreign, vec!["foreign.bin", "decoder"]),
    ] {
        let mut args = vec!["encode", "--model", path_str(model)];
        args.extend(input);
        args.extend(["--name", "x", "--add-to", path_str(add_to)]);
        let e = error_line(&material_nn(&args));
        assert!(expect.iter().all(|w| e.contains(w)), "{e} should name {expect:?}");
    }
    assert_eq!(std::fs::read(&lib).unwrap(), lib_bytes, "library untouched");
    assert_eq!(std::fs::read(&foreign).unwrap(), foreign_bytes, "library untouched");
    let e = error_line(&material_nn(&[
        "export",
        "--run",
        path_str(&run),
        "--out",
        path_str(&dir.path().join("x.bin")),
        "--materials",
        "no-such-material",
    ]));
    assert!(e.contains("no-such-material"), "{e}");
    assert!(!dir.path().join("x.bin").exists());

    // A latent file of another version is refused with its reason.
    let mut bytes = std::fs::read(&latent).unwrap();
    let next = renderer::formats::latent_file::VERSION + 1;
    bytes[8..12].copy_from_slice(&next.to_le_bytes());
    let future = dir.path().join("future.bin");
    std::fs::write(&future, bytes).unwrap();
    let e = error_line(&material_nn(&[
        "encode",
        "--run",
        path_str(&run),
        "--samples",
        path_str(&csv),
        "--add-to",
        path_str(&future),
    ]));
    assert!(e.contains("future.bin") && e.contains(&format!("version {next}")), "{e}");
}

#[test]
fn a_resumed_run_ends_with_the_same_weights() {
    let dir = tempfile::tempdir().unwrap();
    let data = make_data(dir.path());
    let stop = AtomicBool::new(false);
    let whole = dir.path().join("whole");
    train(
        &request(&data, &whole, Some(small_config(3)), false, None),
        &stop,
        &mut |_| {},
    )
    .unwrap();

    // Two training materials: 2 steps per epoch; stop mid-epoch 2, then at the end of epoch 2.
    let parts = dir.path().join("parts");
    let o = train(
        &request(&data, &parts, Some(small_config(3)), false, Some(3)),
        &stop,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(o, Outcome::Interrupted { step: 3 });
    let o = train(
        &request(&data, &parts, None, true, Some(4)),
        &stop,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(o, Outcome::Interrupted { step: 4 });
    let o = train(
        &request(&data, &parts, None, true, None),
        &stop,
        &mut |_| {},
    )
    .unwrap();
    assert_eq!(o, Outcome::Completed);

    let a = Checkpoint::read(&RunDir(whole).checkpoint()).unwrap();
    let b = Checkpoint::read(&RunDir(parts).checkpoint()).unwrap();
    assert_eq!(a.state.step, b.state.step);
    assert_eq!(a.state.rng, b.state.rng);
    let (wa, wb) = (model_weights(&a), model_weights(&b));
    let worst = wa
        .iter()
        .zip(&wb)
        .map(|(x, y)| (x - y).abs())
        .fold(0f32, f32::max);
    assert!(
        wa == wb,
        "weights differ after resuming (largest difference {worst})"
    );
    let losses = |c: &Checkpoint| {
        c.state
            .history
            .iter()
            .map(|r| (r.train_loss, r.validation))
            .collect::<Vec<_>>()
    };
    assert_eq!(losses(&a), losses(&b));

    // The same run with room for one table at a time: every table streamed from its file
    // (each step's, the validation one, f_ref's median), the same weights.
    let streamed = dir.path().join("streamed");
    let mut req = request(&data, &streamed, Some(small_config(3)), false, None);
    req.table_cache_bytes = material_nn::dataset::TABLE_BYTES;
    train(&req, &stop, &mut |_| {}).unwrap();
    let c = Checkpoint::read(&RunDir(streamed.clone()).checkpoint()).unwrap();
    assert!(model_weights(&c) == wa, "a streamed run ends with other weights");
    assert_eq!(losses(&c), losses(&a));
    let reference = |run: &Path| std::fs::read(RunDir(run.to_path_buf()).reference()).unwrap();
    assert!(reference(&streamed) == reference(&dir.path().join("whole")), "f_ref differs");
}

/// Runs with synthetic variants (`augment`) or interpolated frames (`interpolation`) in every
/// step: each changes the weights a plain run ends with, and resumed from a checkpoint after
/// its first step ends with the weights of an uninterrupted run.
#[test]
fn augmented_and_interpolating_runs_resume_to_the_same_weights() {
    let dir = tempfile::tempdir().unwrap();
    let data = make_data(dir.path());
    let stop = AtomicBool::new(false);
    let plain = small_config(2);
    let plain_run = dir.path().join("plain");
    train(&request(&data, &plain_run, Some(plain.clone()), false, None), &stop, &mut |_| {}).unwrap();
    let read = |run: &Path| Checkpoint::read(&RunDir(run.to_path_buf()).checkpoint()).unwrap();
    let variants = [
        ("augmented", TrainConfig { augment: material_nn::augment::Augmentation { share: 1.0, blend: 0.5 }, ..plain.clone() }),
        ("interpolating", TrainConfig { interpolation: material_nn::interpolation::Interpolation { share: 1.0 }, ..plain }),
    ];
    for (name, config) in variants {
        let whole = dir.path().join(format!("{name}-whole"));
        train(&request(&data, &whole, Some(config.clone()), false, None), &stop, &mut |_| {}).unwrap();
        let parts = dir.path().join(format!("{name}-parts"));
        let o = train(&request(&data, &parts, Some(config), false, Some(1)), &stop, &mut |_| {}).unwrap();
        assert_eq!(o, Outcome::Interrupted { step: 1 });
        train(&request(&data, &parts, None, true, None), &stop, &mut |_| {}).unwrap();
        assert!(model_weights(&read(&whole)) == model_weights(&read(&parts)), "an {name} run resumed to other weights");
        assert!(model_weights(&read(&whole)) != model_weights(&read(&plain_run)), "the {name} run changed nothing");
        assert!(read(&whole).state.history.iter().all(|r| r.train_loss.is_finite()), "{name}");
    }
}

#[test]
fn bad_input_gives_one_line_errors() {
    let dir = tempfile::tempdir().unwrap();
    let data = make_data(dir.path());

    // Empty data directory.
    let empty = dir.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let run = dir.path().join("run");
    let e = error_line(&material_nn(&[
        "train",
        "--data",
        path_str(&empty),
        "--out",
        path_str(&run),
    ]));
    assert!(e.contains("empty") && e.contains("no MERL tables"), "{e}");

    // A NaN in a table: the error names the material's file and the bin.
    let nan_dir = dir.path().join("nan");
    std::fs::create_dir(&nan_dir).unwrap();
    let good = std::fs::read(data.join("grey-clay.binary")).unwrap();
    assert_eq!(good.len() as u64, FILE_BYTES);
    std::fs::write(nan_dir.join("grey-clay.binary"), &good).unwrap();
    let mut bad = good;
    let at = HEADER_BYTES as usize + 8 * 1234;
    bad[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    std::fs::write(nan_dir.join("broken-paint.binary"), bad).unwrap();
    let e = error_line(&material_nn(&[
        "train",
        "--data",
        path_str(&nan_dir),
        "--out",
        path_str(&run),
    ]));
    assert!(
        e.contains("broken-paint.binary") && e.contains("NaN") && e.contains("phi_d 154"),
        "{e}"
    );

    // Resuming without a checkpoint; a corrupt and a foreign checkpoint.
    let cfg = dir.path().join("config.json");
    std::fs::write(&cfg, serde_json::to_string(&small_config(1)).unwrap()).unwrap();
    let e = error_line(&material_nn(&[
        "train",
        "--data",
        path_str(&data),
        "--out",
        path_str(&run),
        "--resume",
    ]));
    assert!(e.contains("checkpoint.bin"), "{e}");
    let out = material_nn(&[
        "train",
        "--data",
        path_str(&data),
        "--out",
        path_str(&run),
        "--config",
        path_str(&cfg),
    ]);
    assert!(out.status.success(), "{out:?}");
    let ckpt = RunDir(run.clone()).checkpoint();
    let mut bytes = std::fs::read(&ckpt).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0x55;
    std::fs::write(&ckpt, &bytes).unwrap();
    let e = error_line(&material_nn(&[
        "train",
        "--data",
        path_str(&data),
        "--out",
        path_str(&run),
        "--resume",
    ]));
    assert!(
        e.contains("checkpoint.bin") && e.contains("checksum"),
        "{e}"
    );
    std::fs::write(&ckpt, b"PK\x03\x04 a zip file").unwrap();
    let e = error_line(&material_nn(&[
        "train",
        "--data",
        path_str(&data),
        "--out",
        path_str(&run),
        "--resume",
    ]));
    assert!(e.contains("not a material-nn checkpoint"), "{e}");

    // A configuration with an unknown field.
    std::fs::write(&cfg, "{\"learning_rat\": 0.1}").unwrap();
    let e = error_line(&material_nn(&[
        "train",
        "--data",
        path_str(&data),
        "--out",
        path_str(&dir.path().join("r2")),
        "--config",
        path_str(&cfg),
    ]));
    assert!(
        e.contains("config.json") && e.contains("learning_rat"),
        "{e}"
    );
}

#[test]
fn search_tries_the_grid_then_random_rates() {
    let dir = tempfile::tempdir().unwrap();
    let data = make_data(dir.path());
    let out = dir.path().join("search");
    let stop = AtomicBool::new(false);
    let mut seen = 0;
    let trials =
        material_nn::search::search(&data, &out, &small_config(1), 1, &stop, &mut |_| seen += 1)
            .unwrap();
    assert_eq!((trials.len(), seen), (4, 4));
    assert!(trials.windows(2).all(|p| p[0].score <= p[1].score));
    let best: TrainConfig =
        serde_json::from_str(&std::fs::read_to_string(out.join("best-config.json")).unwrap())
            .unwrap();
    assert_eq!(best.learning_rate, trials[0].learning_rate);
    assert_eq!(
        std::fs::read_to_string(out.join("search.csv"))
            .unwrap()
            .lines()
            .count(),
        5
    );
}

/// A run killed outright (SIGKILL, no chance to save) at arbitrary moments — mid-epoch, or
/// while a checkpoint is being written — always leaves a readable checkpoint or none (they
/// are written to a temporary file and renamed), and resuming from it ends with the same
/// weights and history as an uninterrupted run.
#[test]
fn a_killed_run_resumes_to_the_same_weights() {
    let dir = tempfile::tempdir().unwrap();
    let data = make_data(dir.path());
    let config = dir.path().join("config.json");
    std::fs::write(&config, serde_json::to_string(&small_config(8)).unwrap()).unwrap();
    let args = |run: &Path| {
        let mut a = vec!["train", "--data", path_str(&data), "--out", path_str(run), "--config", path_str(&config)];
        if RunDir(run.to_path_buf()).checkpoint().exists() {
            a.push("--resume");
        }
        a.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let whole = dir.path().join("whole");
    let start = std::time::Instant::now();
    let out = material_nn(&args(&whole).iter().map(String::as_str).collect::<Vec<_>>());
    assert!(out.status.success(), "{out:?}");
    let duration = start.elapsed();

    let parts = dir.path().join("parts");
    let mut killed = 0;
    for fraction in [0.45, 0.5, 0.55, 0.6] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_material-nn"))
            .args(args(&parts))
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .expect("material-nn starts");
        std::thread::sleep(duration.mul_f64(fraction));
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
            killed += 1;
        }
        child.wait().unwrap();
        let ckpt = RunDir(parts.clone()).checkpoint();
        if ckpt.exists() {
            Checkpoint::read(&ckpt).expect("a kill never leaves a corrupt checkpoint");
        }
    }
    assert!(killed > 0, "no run was killed before it finished");
    let out = material_nn(&args(&parts).iter().map(String::as_str).collect::<Vec<_>>());
    assert!(out.status.success(), "{out:?}");
    let a = Checkpoint::read(&RunDir(whole).checkpoint()).unwrap();
    let b = Checkpoint::read(&RunDir(parts).checkpoint()).unwrap();
    assert_eq!(a.state.step, b.state.step);
    assert!(model_weights(&a) == model_weights(&b), "weights differ after kills and resumes");
    let losses = |c: &Checkpoint| c.state.history.iter().map(|r| (r.train_loss, r.validation)).collect::<Vec<_>>();
    assert_eq!(losses(&a), losses(&b));
}
