/*
 * Uses libneural_brdf from C: opens a code of a latent file, evaluates and samples it, and
 * checks that bad input comes back as an error status with a message, never a crash.
 *
 *   cc -std=c99 -I plugins/c/include plugins/c/examples/example.c \
 *      -L target/release -lneural_brdf -lm -o example
 *   LD_LIBRARY_PATH=target/release ./example scenes/materials/latent.bin
 *
 * Exits 0 after printing "ok", or non-zero with the failing step and the library's message.
 */
#include "neural_brdf.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define SAMPLES 4096

static int fail(const char *step) {
    fprintf(stderr, "error: %s: %s\n", step, nb_last_error());
    return 1;
}

static int expect(NbStatus got, NbStatus want, const char *step) {
    if (got != want) {
        fprintf(stderr, "error: %s: status %d, expected %d (%s)\n", step, (int)got, (int)want, nb_last_error());
        return 0;
    }
    printf("%s -> %s\n", step, nb_last_error());
    return 1;
}

/* A copy of the file at `path` with its format version (bytes 8..11) set to 99. */
static int write_wrong_version(const char *path, const char *copy) {
    FILE *in = fopen(path, "rb");
    if (!in) return 0;
    fseek(in, 0, SEEK_END);
    long size = ftell(in);
    fseek(in, 0, SEEK_SET);
    unsigned char *bytes = malloc((size_t)size);
    int ok = bytes && size > 12 && fread(bytes, 1, (size_t)size, in) == (size_t)size;
    fclose(in);
    if (ok) {
        bytes[8] = 99;
        bytes[9] = bytes[10] = bytes[11] = 0;
        FILE *out = fopen(copy, "wb");
        ok = out && fwrite(bytes, 1, (size_t)size, out) == (size_t)size;
        if (out) fclose(out);
    }
    free(bytes);
    return ok;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s LATENT.bin [SCRATCH_FILE]\n", argv[0]);
        return 2;
    }
    NbMaterial *m = NULL;
    if (nb_material_open(argv[1], "alum-bronze", &m) != NB_STATUS_OK) return fail("open alum-bronze");

    /* The mirror configuration and an off-specular pair, both at 36.9 degrees. */
    float wo[6] = {0.0f, 0.6f, 0.8f, 0.0f, 0.6f, 0.8f};
    float wi[6] = {0.0f, -0.6f, 0.8f, 0.6f, 0.0f, 0.8f};
    float f[6], pdf[2];
    if (nb_material_eval_pdf(m, 2, wo, wi, f, pdf) != NB_STATUS_OK) return fail("eval_pdf");
    printf("f(mirror) = %.4g %.4g %.4g 1/sr, pdf %.4g 1/sr\n", f[0], f[1], f[2], pdf[0]);
    printf("f(off-specular) = %.4g %.4g %.4g 1/sr, pdf %.4g 1/sr\n", f[3], f[4], f[5], pdf[1]);
    if (!(f[0] > f[3] && pdf[0] > pdf[1])) {
        fprintf(stderr, "error: the specular peak is not where it should be\n");
        return 1;
    }

    /* Directional albedo at wo by importance sampling: mean of f cos / pdf. */
    static float wos[3 * SAMPLES], us[3 * SAMPLES], wis[3 * SAMPLES], fs[3 * SAMPLES], pdfs[SAMPLES];
    for (int i = 0; i < SAMPLES; ++i) {
        wos[3 * i] = 0.0f, wos[3 * i + 1] = 0.6f, wos[3 * i + 2] = 0.8f;
        us[3 * i] = (i + 0.5f) / SAMPLES;
        us[3 * i + 1] = fmodf(i * 0.6180339887f, 1.0f);
        us[3 * i + 2] = fmodf(i * 0.7548776662f, 1.0f);
    }
    if (nb_material_sample(m, SAMPLES, wos, us, wis, fs, pdfs) != NB_STATUS_OK) return fail("sample");
    double albedo[3] = {0, 0, 0};
    for (int i = 0; i < SAMPLES; ++i) {
        if (pdfs[i] <= 0.0f) continue;
        for (int c = 0; c < 3; ++c) albedo[c] += fs[3 * i + c] * wis[3 * i + 2] / pdfs[i] / SAMPLES;
    }
    printf("albedo at 36.9 degrees = %.3f %.3f %.3f\n", albedo[0], albedo[1], albedo[2]);
    for (int c = 0; c < 3; ++c) {
        if (!(albedo[c] > 0.05 && albedo[c] < 1.01)) {
            fprintf(stderr, "error: albedo %f out of range\n", albedo[c]);
            return 1;
        }
    }

    /* Bad input: an error status and a message, nothing opened, no crash. */
    NbMaterial *bad = NULL;
    if (!expect(nb_material_open("/nonexistent/latent.bin", "alum-bronze", &bad), NB_STATUS_IO, "missing file")) return 1;
    if (!expect(nb_material_open(argv[1], "no-such-material", &bad), NB_STATUS_UNKNOWN_NAME, "unknown name")) return 1;
    if (argc > 2) {
        if (!write_wrong_version(argv[1], argv[2])) return fail("writing the wrong-version copy");
        if (!expect(nb_material_open(argv[2], "alum-bronze", &bad), NB_STATUS_INVALID_FILE, "wrong version")) return 1;
        remove(argv[2]);
    }
    if (bad != NULL) {
        fprintf(stderr, "error: a failed open returned a handle\n");
        return 1;
    }
    float nan_dir[3] = {NAN, 0.0f, 1.0f};
    if (!expect(nb_material_eval(m, 1, nan_dir, wi, f), NB_STATUS_INVALID_ARGUMENT, "NaN direction")) return 1;
    if (!expect(nb_material_eval(m, 1, wo, wi, NULL), NB_STATUS_INVALID_ARGUMENT, "NULL output")) return 1;

    /* Spatially varying materials at one point: the blend of two codes at t (the latent
       interpolation decoded, as render --sweep does) and a mixture with weights. */
    NbMaterial *blend = NULL, *mix = NULL;
    if (nb_material_open_blend(argv[1], "alum-bronze", "chrome", 0.25f, &blend) != NB_STATUS_OK) return fail("open blend");
    const NbMaterial *parts[2] = {m, blend};
    float weights[2] = {1.0f, 3.0f};
    if (nb_material_open_mix(parts, weights, 2, &mix) != NB_STATUS_OK) return fail("open mix");
    float fm[3], fb[3], fx[3];
    if (nb_material_eval(m, 1, wo, wi, fm) != NB_STATUS_OK || nb_material_eval(blend, 1, wo, wi, fb) != NB_STATUS_OK) return fail("eval parts");
    /* The mixture shares its parts' data: the part handles may go first. */
    nb_material_free(blend);
    if (nb_material_eval(mix, 1, wo, wi, fx) != NB_STATUS_OK) return fail("eval mix");
    printf("f(mirror): blend at t = 0.25 %.4g %.4g %.4g, mix 1:3 %.4g %.4g %.4g 1/sr\n", fb[0], fb[1], fb[2], fx[0], fx[1], fx[2]);
    for (int c = 0; c < 3; ++c) {
        float expected = 0.25f * fm[c] + 0.75f * fb[c];
        if (!(fabsf(fx[c] - expected) <= 1e-5f * expected)) {
            fprintf(stderr, "error: mixture %g, expected %g\n", fx[c], expected);
            return 1;
        }
    }
    if (!expect(nb_material_open_blend(argv[1], "alum-bronze", "chrome", NAN, &bad), NB_STATUS_INVALID_ARGUMENT, "blend at t NaN")) return 1;
    if (!expect(nb_material_open_blend(argv[1], "alum-bronze", "chrome", 1.5f, &bad), NB_STATUS_INVALID_ARGUMENT, "blend at t 1.5")) return 1;
    if (!expect(nb_material_open_blend(argv[1], "alum-bronze", "no-such-material", 0.5f, &bad), NB_STATUS_UNKNOWN_NAME, "blend of an unknown code")) return 1;
    const NbMaterial *five[5] = {m, m, m, m, m};
    float five_weights[5] = {1.0f, 1.0f, 1.0f, 1.0f, 1.0f};
    float negative[2] = {1.0f, -1.0f}, not_a_number[2] = {NAN, 1.0f};
    const NbMaterial *with_null[2] = {m, NULL};
    if (!expect(nb_material_open_mix(five, five_weights, 5, &bad), NB_STATUS_INVALID_ARGUMENT, "mix of 5")) return 1;
    if (!expect(nb_material_open_mix(five, negative, 2, &bad), NB_STATUS_INVALID_ARGUMENT, "negative weight")) return 1;
    if (!expect(nb_material_open_mix(five, not_a_number, 2, &bad), NB_STATUS_INVALID_ARGUMENT, "NaN weight")) return 1;
    if (!expect(nb_material_open_mix(with_null, weights, 2, &bad), NB_STATUS_INVALID_ARGUMENT, "NULL part")) return 1;
    if (!expect(nb_material_open_mix(NULL, weights, 2, &bad), NB_STATUS_INVALID_ARGUMENT, "NULL parts")) return 1;
    if (bad != NULL) {
        fprintf(stderr, "error: a failed blend or mix returned a handle\n");
        return 1;
    }
    nb_material_free(mix);

    nb_material_free(m);
    printf("ok\n");
    return 0;
}
