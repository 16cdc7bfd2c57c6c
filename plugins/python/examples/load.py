"""neural_brdf from many Python threads at once: THREADS threads share two materials (a decoded
code and a mixture of it with a blend) and call eval, pdf and sample on batches of BATCH
pairs, CALLS calls in all; every result must equal, bit for bit, what one thread got for the
same batch before the threads started. The package releases the GIL during each batched call,
so the threads' calls overlap in native code. Prints the calls, pairs, wall time and
throughput; exits 1 on a difference or an error.

    PYTHONPATH=target/release/python-plugin python3 plugins/python/examples/load.py \\
        scenes/materials/latent.bin --threads 8 --calls 10000000 --batch 4

(`cargo test --release -p neural-brdf-python --test python` assembles the package there.)
`tests/test_threads.py` runs the same at a small size.
"""

import argparse
import sys
import threading
import time

import numpy as np

import neural_brdf

BATCHES = 64


def inputs(batch, seed=54):
    """BATCHES batches of (wo, wi, u): directions over the whole sphere (a fifth below the
    horizon) and uniform numbers, float32."""
    rng = np.random.default_rng(seed)

    def directions():
        z = rng.uniform(-0.2, 1.0, (BATCHES, batch))
        phi = rng.uniform(0, 2 * np.pi, (BATCHES, batch))
        r = np.sqrt(np.maximum(0, 1 - z * z))
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1).astype(np.float32)

    return directions(), directions(), rng.random((BATCHES, batch, 3), dtype=np.float32)


def calls(m, wo, wi, u):
    """The three calls on one batch."""
    return (m.eval(wo, wi), m.pdf(wo, wi)) + tuple(m.sample(wo, u))


def run(latent, threads=8, total_calls=3000, batch=4):
    """Runs the load; returns (calls, pairs, seconds). Raises AssertionError on a result that
    differs from one thread's."""
    code = neural_brdf.Material.open(latent, "alum-bronze")
    blend = neural_brdf.Material.blend(latent, "alum-bronze", "chrome", 0.25)
    materials = [code, neural_brdf.Material.mix([code, blend], [0.6, 0.4])]
    wo, wi, u = inputs(batch)
    reference = [[calls(m, wo[b], wi[b], u[b]) for b in range(BATCHES)] for m in materials]
    rounds = max(1, total_calls // (3 * threads))
    failures = []

    def worker(t):
        try:
            for c in range(rounds):
                k, b = c % 2, (7 * t + c) % BATCHES
                got = calls(materials[k], wo[b], wi[b], u[b])
                for x, y in zip(got, reference[k][b]):
                    if not np.array_equal(x, y):
                        raise AssertionError(f"thread {t}, call {c}: results differ from one thread's")
        except Exception as e:  # reported by the main thread
            failures.append(e)

    pool = [threading.Thread(target=worker, args=(t,)) for t in range(threads)]
    start = time.perf_counter()
    for th in pool:
        th.start()
    for th in pool:
        th.join()
    seconds = time.perf_counter() - start
    if failures:
        raise failures[0]
    n = threads * rounds * 3
    return n, n * batch, seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("latent")
    parser.add_argument("--threads", type=int, default=8)
    parser.add_argument("--calls", type=int, default=300_000)
    parser.add_argument("--batch", type=int, default=4)
    args = parser.parse_args()
    try:
        n, pairs, seconds = run(args.latent, args.threads, args.calls, args.batch)
    except AssertionError as e:
        print(f"error: {e}", file=sys.stderr)
        return 1
    print(f"{args.threads} threads, {n} calls of {args.batch} pairs (eval, pdf, sample; a code and a mixture) "
          f"in {seconds:.2f} s: {n / seconds:.0f} calls/s, {pairs / seconds:.0f} pairs/s")
    print("ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
