"""The benchmark's tiny run, shared by tests/bench/test_bench.py and tests/bench/test_activity.py (one run per
session: it takes about two minutes on 2 cores, most of it compiling)."""

import pytest


@pytest.fixture(scope="session")
def bench_run(tmp_path_factory, taichi_cpu):
    from taichi_rocks.bench.run import run_bench

    out = tmp_path_factory.mktemp("bench")
    res = run_bench(out_dir=out, quick=True, tiny=True, progress=False)
    return out, res
