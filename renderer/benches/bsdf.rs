//! BSDF throughput: eval and sample of every BSDF (Lambert, glTF metallic-roughness, tabulated
//! MERL, NBRDF network, decoded FreNBRDF latent), the FreNBRDF target net alone (one point and
//! batches) against the f32 FMA peak of one core of this CPU, and the latent decode time.
//!
//! Data: the NBRDF network of alum-bronze from `../shared/data/nbrdf/merl` (its tabulation
//! serves as the MERL table) and the shipped `scenes/materials/latent.bin`.
//! Run: `cargo bench -p renderer --bench bsdf`; the FLOP-utilisation summary is printed first.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::{Vec2, Vec3};
use renderer::bsdf::merl::{Interpolation, MerlBsdf};
use renderer::bsdf::nbrdf::NbrdfBsdf;
use renderer::bsdf::tabulated_sampling::TabulatedSamplerConfig;
use renderer::bsdf::{Bxdf, Lambert, MetallicRoughness};
use renderer::neural::latent_library::LatentLibrary;
use renderer::formats::merl::MerlTable;
use renderer::neural::nbrdf::NbrdfNetwork;
use renderer::neural::target_net::{Kernel, TargetNet, INPUTS, OUTPUTS};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;

const MATERIAL: &str = "alum-bronze";
/// Direction pairs per iteration.
const PAIRS: usize = 4096;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn latents() -> LatentLibrary {
    LatentLibrary::load(&[repo().join("scenes/materials/latent.bin")]).expect("shipped latent file")
}

/// Deterministic directions in the upper hemisphere, with 2D samples.
fn directions() -> Vec<(Vec3, Vec3, Vec2, f32)> {
    let mut state = 0x2545f491u32;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        (state >> 8) as f32 / (1 << 24) as f32
    };
    let dir = |next: &mut dyn FnMut() -> f32| {
        let (z, phi) = (next().max(1e-3), std::f32::consts::TAU * next());
        let r = (1.0 - z * z).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    };
    (0..PAIRS)
        .map(|_| (dir(&mut next), dir(&mut next), Vec2::new(next(), next()), next()))
        .collect()
}

fn bench_bsdf<B: Bxdf>(c: &mut Criterion, name: &str, bsdf: &B) {
    let dirs = directions();
    let mut group = c.benchmark_group("bsdf");
    group.throughput(Throughput::Elements(PAIRS as u64));
    group.bench_function(format!("{name} eval"), |b| {
        b.iter(|| dirs.iter().fold(Vec3::ZERO, |acc, (wo, wi, _, _)| acc + bsdf.eval(*wo, *wi)))
    });
    group.bench_function(format!("{name} sample"), |b| {
        b.iter(|| {
            dirs.iter()
                .filter_map(|(wo, _, u, uc)| bsdf.sample(*wo, *u, *uc))
                .fold(0.0, |acc, s| acc + s.pdf)
        })
    });
    group.finish();
}

fn bsdfs(c: &mut Criterion) {
    bench_bsdf(c, "lambert", &Lambert { albedo: Vec3::splat(0.5) });
    bench_bsdf(c, "metallic-roughness", &MetallicRoughness::new(Vec3::new(0.9, 0.6, 0.3), 1.0, 0.3));
    let network = NbrdfNetwork::load(repo().join("../shared/data/nbrdf/merl").join(MATERIAL)).expect("NBRDF network");
    let table = MerlTable::from_fn(|th, td, pd| network.eval_angles(th, td, pd));
    let merl = MerlBsdf::new(&table, Interpolation::default(), &TabulatedSamplerConfig::default());
    bench_bsdf(c, "merl (trilinear)", &merl);
    bench_bsdf(c, "nbrdf", &NbrdfBsdf::new(network, &TabulatedSamplerConfig::default()));
    bench_bsdf(c, "frenbrdf", &latents().decode(MATERIAL).expect("shipped latent"));
}

fn decode(c: &mut Criterion) {
    let lib = latents();
    lib.decode(MATERIAL).expect("warm-up: converts f_ref once");
    let mut group = c.benchmark_group("latent");
    group.sample_size(10);
    group.bench_function("decode (hypernetwork + packing + sampler fit)", |b| {
        b.iter(|| lib.decode(MATERIAL).expect("decode"))
    });
    group.finish();
}

fn inputs() -> Vec<[f32; INPUTS]> {
    directions()
        .iter()
        .map(|(wo, wi, _, _)| renderer::brdf_coords::network_input(*wi, *wo))
        .collect()
}

fn target_net(c: &mut Criterion) {
    let lib = latents();
    let code = lib.latent(MATERIAL).expect("latent");
    let file = renderer::formats::latent_file::LatentFile::read(repo().join("scenes/materials/latent.bin")).expect("file");
    let mlp = file.decode(&code.z, code.offset, &code.residual);
    let xs = inputs();
    let mut ys = vec![[0.0; OUTPUTS]; xs.len()];
    let mut group = c.benchmark_group("target net");
    group.throughput(Throughput::Elements(xs.len() as u64));
    for kernel in [Kernel::Avx512, Kernel::Avx2Fma, Kernel::Portable] {
        let net = TargetNet::with_kernel(&mlp, kernel).expect("net");
        if net.kernel() != kernel {
            continue;
        }
        group.bench_function(format!("{kernel:?} one point"), |b| {
            b.iter(|| xs.iter().fold(0.0, |acc, x| acc + net.forward(*x)[0]))
        });
        group.bench_function(format!("{kernel:?} batch"), |b| {
            b.iter(|| {
                net.forward_batch(&xs, &mut ys);
                black_box(&ys);
            })
        });
    }
    group.finish();
}

/// The NBRDF network alone: one point at a time against batches (which share each weight
/// load among several points).
fn nbrdf_network(c: &mut Criterion) {
    let network = NbrdfNetwork::load(repo().join("../shared/data/nbrdf/merl").join(MATERIAL)).expect("NBRDF network");
    let xs = inputs();
    let mut ys = vec![[0.0; OUTPUTS]; xs.len()];
    let mut group = c.benchmark_group("nbrdf network");
    group.throughput(Throughput::Elements(xs.len() as u64));
    group.bench_function("one point", |b| b.iter(|| xs.iter().fold(0.0, |acc, x| acc + network.forward(*x)[0])));
    group.bench_function("batch", |b| {
        b.iter(|| {
            network.forward_batch(&xs, &mut ys);
            black_box(&ys);
        })
    });
    group.finish();
}

/// Measured f32 FLOP/s of one core: independent FMA chains, 32 (AVX-512) or 16 (AVX2)
/// registers wide, long enough to hide the latency.
fn peak_flops() -> Option<(f64, &'static str)> {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::*;
        const ITERS: usize = 20_000_000;
        #[target_feature(enable = "avx512f")]
        fn avx512() -> f32 {
            let mut acc = [_mm512_set1_ps(1.0); 16];
            let (m, a) = (_mm512_set1_ps(0.999_999), _mm512_set1_ps(1e-7));
            for _ in 0..ITERS {
                for r in acc.iter_mut() {
                    *r = _mm512_fmadd_ps(*r, m, a);
                }
            }
            acc.iter().map(|r| _mm512_reduce_add_ps(*r)).sum()
        }
        #[target_feature(enable = "avx2,fma")]
        fn avx2() -> f32 {
            let mut acc = [_mm256_set1_ps(1.0); 12];
            let (m, a) = (_mm256_set1_ps(0.999_999), _mm256_set1_ps(1e-7));
            for _ in 0..ITERS {
                for r in acc.iter_mut() {
                    *r = _mm256_fmadd_ps(*r, m, a);
                }
            }
            let mut out = [0f32; 8];
            // SAFETY: `out` holds 8 floats.
            unsafe { _mm256_storeu_ps(out.as_mut_ptr(), acc.iter().fold(_mm256_setzero_ps(), |s, r| _mm256_add_ps(s, *r))) };
            out.iter().sum()
        }
        let start = Instant::now();
        let (flops, name) = if std::is_x86_feature_detected!("avx512f") {
            // SAFETY: the CPU reported AVX-512F.
            black_box(unsafe { avx512() });
            (ITERS as f64 * 16.0 * 16.0 * 2.0, "AVX-512 FMA")
        } else if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
            // SAFETY: the CPU reported AVX2 and FMA.
            black_box(unsafe { avx2() });
            (ITERS as f64 * 12.0 * 8.0 * 2.0, "AVX2 FMA")
        } else {
            return None;
        };
        Some((flops / start.elapsed().as_secs_f64(), name))
    }
    #[cfg(not(target_arch = "x86_64"))]
    None
}

/// Prints evaluations/s of the target net (one thread) as a fraction of the measured peak.
fn flop_utilisation(_: &mut Criterion) {
    let Some((peak, name)) = peak_flops() else {
        eprintln!("no FMA peak measured on this CPU");
        return;
    };
    let lib = latents();
    let file = renderer::formats::latent_file::LatentFile::read(repo().join("scenes/materials/latent.bin")).expect("file");
    let code = lib.latent(MATERIAL).expect("latent");
    let net = TargetNet::new(&file.decode(&code.z, code.offset, &code.residual)).expect("net");
    let xs = inputs();
    let mut ys = vec![[0.0; OUTPUTS]; xs.len()];
    let rounds = 400;
    let time = |f: &mut dyn FnMut()| {
        f();
        let start = Instant::now();
        for _ in 0..rounds {
            f();
        }
        (rounds * xs.len()) as f64 / start.elapsed().as_secs_f64()
    };
    let batch = time(&mut || {
        net.forward_batch(&xs, &mut ys);
        black_box(&ys);
    });
    let single = time(&mut || {
        black_box(xs.iter().fold(0.0, |acc, x| acc + net.forward(*x)[0]));
    });
    let flops = net.flops_per_eval() as f64;
    eprintln!(
        "target net ({:?} kernel, {} FLOP/eval dense): peak {:.1} GFLOP/s/core ({name}); batch {:.2} M evals/s = {:.0}% of peak; one point {:.2} M evals/s = {:.0}% (dense FLOPs: rows of zero inputs are skipped, so above 100 % is possible)",
        net.kernel(),
        flops,
        peak * 1e-9,
        batch * 1e-6,
        100.0 * batch * flops / peak,
        single * 1e-6,
        100.0 * single * flops / peak
    );
}

criterion_group!(benches, flop_utilisation, target_net, nbrdf_network, bsdfs, decode);
criterion_main!(benches);
