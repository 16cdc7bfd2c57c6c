/*
 * libneural_brdf from many threads at once: THREADS threads share two handles (a decoded
 * code and a mixture of it with a blend) and call nb_material_eval, nb_material_pdf and
 * nb_material_sample on batches of BATCH pairs, CALLS calls per thread in all; every result
 * must equal, bit for bit, what one thread got for the same batch before the threads
 * started. Prints the calls, pairs and wall time, and the throughput.
 *
 *   cc -std=c99 -O2 -pthread -I plugins/c/include plugins/c/examples/threads.c \
 *      -L target/release -lneural_brdf -lm -o threads
 *   LD_LIBRARY_PATH=target/release ./threads scenes/materials/latent.bin 8 1250000 4
 *
 * Exits 0 after printing "ok", or non-zero with the failing thread, call and message.
 */
#define _POSIX_C_SOURCE 199309L
#include "neural_brdf.h"

#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Distinct batches: thread t's call c uses batch (7 t + c) mod BATCHES. */
#define BATCHES 64

static const NbMaterial *materials[2];
static size_t batch_size;
static long calls_per_thread;
static float *wo, *wi, *u;                         /* BATCHES * batch_size pairs */
static float *ref_f[2], *ref_pdf[2], *ref_wi[2], *ref_sf[2], *ref_spdf[2];

/* A deterministic stream of numbers in [0, 1). */
static float next_uniform(unsigned long long *state) {
    *state = *state * 6364136223846793005ULL + 1442695040888963407ULL;
    return (float)(*state >> 40) / 16777216.0f;
}

/* A direction over the whole sphere (a fifth of them below the horizon). */
static void direction(unsigned long long *state, float *d) {
    float z = 1.2f * next_uniform(state) - 0.2f, phi = 6.2831853f * next_uniform(state);
    float r = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    d[0] = r * cosf(phi), d[1] = r * sinf(phi), d[2] = z;
}

/* The three calls on batch b of material k into the given outputs. */
static int run_batch(int k, size_t b, float *f, float *pdf, float *swi, float *sf, float *spdf) {
    size_t at = b * batch_size;
    if (nb_material_eval(materials[k], batch_size, wo + 3 * at, wi + 3 * at, f) != NB_STATUS_OK) return 0;
    if (nb_material_pdf(materials[k], batch_size, wo + 3 * at, wi + 3 * at, pdf) != NB_STATUS_OK) return 0;
    if (nb_material_sample(materials[k], batch_size, wo + 3 * at, u + 3 * at, swi, sf, spdf) != NB_STATUS_OK) return 0;
    return 1;
}

static void *worker(void *arg) {
    long t = (long)arg;
    size_t n = batch_size;
    float *f = malloc(3 * n * sizeof(float)), *pdf = malloc(n * sizeof(float));
    float *swi = malloc(3 * n * sizeof(float)), *sf = malloc(3 * n * sizeof(float)), *spdf = malloc(n * sizeof(float));
    long failed = 0;
    for (long c = 0; c < calls_per_thread / 3 && !failed; ++c) {
        int k = (int)(c % 2);
        size_t b = (size_t)(7 * t + c) % BATCHES, at = b * n;
        if (!run_batch(k, b, f, pdf, swi, sf, spdf)) {
            fprintf(stderr, "error: thread %ld, call %ld: %s\n", t, c, nb_last_error());
            failed = 1;
        } else if (memcmp(f, ref_f[k] + 3 * at, 3 * n * sizeof(float)) || memcmp(pdf, ref_pdf[k] + at, n * sizeof(float)) ||
                   memcmp(swi, ref_wi[k] + 3 * at, 3 * n * sizeof(float)) || memcmp(sf, ref_sf[k] + 3 * at, 3 * n * sizeof(float)) ||
                   memcmp(spdf, ref_spdf[k] + at, n * sizeof(float))) {
            fprintf(stderr, "error: thread %ld, call %ld: results differ from one thread's\n", t, c);
            failed = 1;
        }
    }
    free(f), free(pdf), free(swi), free(sf), free(spdf);
    return (void *)failed;
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: %s LATENT.bin THREADS CALLS_PER_THREAD BATCH\n", argv[0]);
        return 2;
    }
    long threads = atol(argv[2]);
    calls_per_thread = atol(argv[3]);
    batch_size = (size_t)atol(argv[4]);
    if (threads < 1 || threads > 256 || calls_per_thread < 3 || batch_size < 1) {
        fprintf(stderr, "error: bad THREADS, CALLS_PER_THREAD or BATCH\n");
        return 2;
    }
    NbMaterial *code = NULL, *blend = NULL, *mix = NULL;
    if (nb_material_open(argv[1], "alum-bronze", &code) != NB_STATUS_OK ||
        nb_material_open_blend(argv[1], "alum-bronze", "chrome", 0.25f, &blend) != NB_STATUS_OK) {
        fprintf(stderr, "error: open: %s\n", nb_last_error());
        return 1;
    }
    const NbMaterial *parts[2] = {code, blend};
    float weights[2] = {0.6f, 0.4f};
    if (nb_material_open_mix(parts, weights, 2, &mix) != NB_STATUS_OK) {
        fprintf(stderr, "error: open mix: %s\n", nb_last_error());
        return 1;
    }
    nb_material_free(blend);
    materials[0] = code, materials[1] = mix;

    size_t pairs = BATCHES * batch_size;
    wo = malloc(3 * pairs * sizeof(float)), wi = malloc(3 * pairs * sizeof(float)), u = malloc(3 * pairs * sizeof(float));
    unsigned long long state = 54;
    for (size_t i = 0; i < pairs; ++i) {
        direction(&state, wo + 3 * i);
        direction(&state, wi + 3 * i);
        for (int c = 0; c < 3; ++c) u[3 * i + c] = next_uniform(&state);
    }
    for (int k = 0; k < 2; ++k) {
        ref_f[k] = malloc(3 * pairs * sizeof(float)), ref_pdf[k] = malloc(pairs * sizeof(float));
        ref_wi[k] = malloc(3 * pairs * sizeof(float)), ref_sf[k] = malloc(3 * pairs * sizeof(float));
        ref_spdf[k] = malloc(pairs * sizeof(float));
        for (size_t b = 0; b < BATCHES; ++b) {
            size_t at = b * batch_size;
            if (!run_batch(k, b, ref_f[k] + 3 * at, ref_pdf[k] + at, ref_wi[k] + 3 * at, ref_sf[k] + 3 * at, ref_spdf[k] + at)) {
                fprintf(stderr, "error: one thread: %s\n", nb_last_error());
                return 1;
            }
        }
    }

    pthread_t *ids = malloc((size_t)threads * sizeof(pthread_t));
    double start = now();
    for (long t = 0; t < threads; ++t) {
        if (pthread_create(&ids[t], NULL, worker, (void *)t) != 0) {
            fprintf(stderr, "error: pthread_create\n");
            return 1;
        }
    }
    int failed = 0;
    for (long t = 0; t < threads; ++t) {
        void *result;
        pthread_join(ids[t], &result);
        failed |= result != NULL;
    }
    double seconds = now() - start;
    long calls = threads * (calls_per_thread / 3) * 3;
    printf("%ld threads, %ld calls of %zu pairs (eval, pdf, sample; a code and a mixture) in %.2f s: %.0f calls/s, %.0f pairs/s\n",
           threads, calls, batch_size, seconds, calls / seconds, calls * (double)batch_size / seconds);

    nb_material_free(mix);
    nb_material_free(code);
    free(ids), free(wo), free(wi), free(u);
    for (int k = 0; k < 2; ++k) free(ref_f[k]), free(ref_pdf[k]), free(ref_wi[k]), free(ref_sf[k]), free(ref_spdf[k]);
    if (failed) return 1;
    printf("ok\n");
    return 0;
}
