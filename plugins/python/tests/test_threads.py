"""Eight Python threads share materials and call eval, pdf and sample at once (the GIL released
in each batched call): every result equals one thread's bit for bit. The load run of
docs/fuzzing.md is examples/load.py at 10 M calls; this is it at 2,400."""

import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parents[1] / "examples"))

import load  # noqa: E402


def test_eight_threads_get_one_threads_results(latent_path):
    calls, pairs, seconds = load.run(latent_path, threads=8, total_calls=2400, batch=4)
    assert calls == 2400 and pairs == 9600 and seconds > 0
