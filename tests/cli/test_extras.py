"""``pip install clbeam`` without extras: image, peaks, simulate, demo, devices,
forward and avo work; survey, profile and bench say in one line which extra
they need.  The optional packages are made unimportable in a child process,
as in an environment without them."""

from __future__ import annotations

import subprocess
import sys

import pytest

#: the optional dependencies of the survey, segy and bench extras
OPTIONAL = ("dask", "distributed", "pyproj", "segyio", "numba")

# a None entry in sys.modules is how Python marks a module as absent: import raises, find_spec says None
RUNNER = f"""
import sys
sys.modules.update(dict.fromkeys({OPTIONAL!r}))
from clbeam.cli.main import main
sys.exit(main(sys.argv[1:]))
"""


def clbeam(*argv, cwd):
    return subprocess.run([sys.executable, "-c", RUNNER, *map(str, argv)], capture_output=True, text=True, cwd=cwd,
                          timeout=600)


def test_the_blocker_really_blocks(tmp_path):
    r = subprocess.run([sys.executable, "-c", RUNNER.replace("from clbeam.cli.main import main\nsys.exit(main(sys.argv[1:]))",
                                                             "import dask")], capture_output=True, text=True)
    assert r.returncode != 0 and "ModuleNotFoundError" in r.stderr and "dask" in r.stderr


@pytest.mark.slow
def test_base_commands_run_without_the_optional_packages(tmp_path):
    pings, images, peaks = tmp_path / "p.nc", tmp_path / "i.nc", tmp_path / "k.csv"
    r = clbeam("simulate", "-o", pings, "--scene", "line1", "--pings", "2", "--max-range", "400", "-q", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    r = clbeam("image", pings, "-o", images, "--range-res", "0.5", "--angle-res", "0.5", "--max-range", "400", "-q",
               cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    r = clbeam("peaks", images, "-o", peaks, "--mlh", "-q", cwd=tmp_path)
    assert r.returncode == 0 and peaks.read_text().count("\n") > 2, r.stderr
    r = clbeam("avo", images, "-o", tmp_path / "avo.csv", "--pings-per-patch", "1", "--no-invert", "-q", cwd=tmp_path)
    assert r.returncode == 0 and (tmp_path / "avo.csv").read_text().count("\n") == 5, r.stderr  # 2 pings x 2 sides
    r = clbeam("demo", "-o", tmp_path / "demo", "--pings", "1", "-q", cwd=tmp_path)
    assert r.returncode == 0 and (tmp_path / "demo" / "ping000.png").stat().st_size > 0, r.stderr
    assert clbeam("devices", cwd=tmp_path).returncode == 0
    r = clbeam("forward", "--layers", "table2-layout1", "-o", tmp_path / "fwd", "-q", cwd=tmp_path)
    assert r.returncode == 0 and (tmp_path / "fwd" / "table2-layout1_trace.csv").exists(), r.stderr


@pytest.mark.parametrize("argv, extra", [
    (["survey", "x.nc", "-o", "out.zarr"], "survey"),
    (["profile", "x.nc", "-o", "p.sgy"], "segy"),
    (["bench", "-o", "b"], "bench"),
])
def test_commands_needing_an_extra_say_which_in_one_line(tmp_path, argv, extra):
    r = clbeam(*argv, cwd=tmp_path)
    err = r.stderr.strip()
    assert r.returncode == 2 and "\n" not in err
    assert err.startswith("clbeam: error:") and f"pip install 'clbeam[{extra}]'" in err
