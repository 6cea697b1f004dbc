"""Every kernel variant under Oclgrind: no invalid or uninitialised memory
access on grids whose delays leave the record, and results equal to the
reference (beam-sampled imaging: the beam-to-grid kernel against its NumPy
form on the same beams)."""

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).parent

pytestmark = [pytest.mark.oclgrind, pytest.mark.slow]


def test_kernels_are_clean_under_oclgrind():
    oclgrind = shutil.which("oclgrind")
    assert oclgrind, "oclgrind is not installed (Debian package 'oclgrind'; the set-up script installs it)"
    env = dict(os.environ, CLBEAM_DEVICE="")
    r = subprocess.run([oclgrind, "--uninitialized", "--check-api", "--data-races", sys.executable,
                        str(HERE.parent / "oclgrind_run.py")], capture_output=True, text=True, env=env, timeout=900)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out[-3000:]
    assert "device: Oclgrind Simulator" in r.stdout, out[-2000:]
    # Oclgrind reports each problem as a block of lines ("Invalid read", "Uninitialized value",
    # "data race", API errors).  pyopencl itself probes clGetDeviceInfo for parameters Oclgrind
    # does not know when it builds a program: those blocks are not about the kernels.
    blocks = [b for b in re.split(r"\n\s*\n", r.stderr) if b.strip()]
    problems = [b for b in blocks if re.search(r"invalid|uninitiali[sz]ed|data race|out-of-bounds|error|fatal", b, re.I)
                and "Function: clGetDeviceInfo" not in b]
    assert not problems, "\n".join(problems[:20])
    variants = [line for line in r.stdout.splitlines() if line.startswith("variant")]
    assert len(variants) >= 80  # 6 modes x (2 precisions + 2 more layouts), each plain, apodized, ray-traced; beams
    assert sum("apodized" in line for line in variants) >= 24 and sum("tables" in line for line in variants) >= 24
    assert sum(line.startswith("variant beams") for line in variants) >= 12
    assert sum(line.startswith("variant beams-window") for line in variants) >= 4  # packed cells of a band
    assert sum(line.startswith("variant points-tables") for line in variants) >= 8  # sub-cell refinement
    for line in variants:
        rel = float(re.search(r"rel=(\S+)", line).group(1))
        assert rel < 1e-4 and "m_equal=True" in line, line
        assert "m_range=0-" in line  # some cells lie outside the record for every channel
