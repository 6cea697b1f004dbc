"""Run time of the scene simulator (pytest-benchmark).

What is timed, on one core (set ``OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1``):

- ``test_bench_line1_ping``: one ping of the ``line1`` scene rendered by a
  prepared :class:`~clbeam.sim.simulator.Simulator` — 64 channels, 40 534 samples
  (1.01 s at 40 kHz, ranges to 700 m), about 20 000 scatterers (three
  pipelines, two rough interfaces, five specular paths) and noise.  The
  cost scales with scatterers × channels, plus one FFT per channel.
- ``test_bench_line1_setup``: preparing all 56 pings (delay tables, the
  world-fixed random interfaces, the pipeline points).
- ``test_bench_line4_ping``: one ``line4`` ping (ranges to 1000 m).

Run with ``pytest bench/test_bench_simulate.py --benchmark-enable``; the
project's default ``--benchmark-disable`` runs each once as a smoke test.
"""

from __future__ import annotations

import pytest

from clbeam.sim.simulator import Simulator


@pytest.fixture(scope="module")
def line1():
    return Simulator("line1", pings=range(4))


def _record_size(benchmark, sim, index):
    g = sim.geometry(index)
    benchmark.extra_info["scatterers"] = int(sum(len(e) for e in sim.echoes(g)))
    benchmark.extra_info["channels"] = int(sim.scene.sonar.n_elements)
    benchmark.extra_info["samples"] = int(sim.n_samples)


def test_bench_line1_ping(benchmark, line1):
    _record_size(benchmark, line1, 1)
    samples = benchmark.pedantic(line1.ping, args=(1,), rounds=5, warmup_rounds=1)
    assert samples.shape == (64, line1.n_samples)


def test_bench_line1_setup(benchmark):
    sim = benchmark.pedantic(Simulator, args=("line1",), kwargs={"pings": range(56)}, rounds=3)
    assert len(sim.indices) == 56


def test_bench_line4_ping(benchmark):
    sim = Simulator("line4", pings=[30])
    _record_size(benchmark, sim, 30)
    samples = benchmark.pedantic(sim.ping, args=(30,), rounds=3, warmup_rounds=1)
    assert samples.shape == (64, sim.n_samples)
