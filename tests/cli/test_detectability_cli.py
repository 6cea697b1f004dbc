"""``clbeam detectability`` (docs/detectability.md): the table, a fifty-range sweep, one-line errors."""

import csv
import importlib.resources

import numpy as np
import pytest

from clbeam.cli.main import main


def _rows(path):
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_one_row_per_pipeline_at_its_mean_range(tmp_path):
    out = tmp_path / "pd.csv"
    assert main(["detectability", "line4", "-o", str(out), "-q"]) == 0
    rows = _rows(out)
    assert [r["target"] for r in rows] == ["A", "B", "C"]
    # the scene's pipelines: A crosses the first ping at 595 m and curves away; the mean over the pings is nearer
    for r, y0 in zip(rows, (595.0, 780.0, 920.0)):
        assert 0.85 * y0 < float(r["range_m"]) <= y0 + 1e-6
        assert 0.0 <= float(r["pd"]) <= 1.0


def test_a_fifty_range_sweep_writes_a_row_per_pipeline_and_range_and_the_figure(tmp_path):
    """At the pipelines' own headings: B and C cross 3.5 and 5 degrees off broadside, their echoes summed
    along the pipe (the slower case; its time is measured in docs/detectability.md, not asserted here)."""
    out = tmp_path / "sweep.csv"
    assert main(["detectability", "line4", "-o", str(out), "--ranges", "220:955:15", "-q"]) == 0
    rows = _rows(out)
    assert len(rows) == 3 * 50 and {"target", "range_m", "pd"} <= set(rows[0])
    np.testing.assert_allclose(sorted({float(r["range_m"]) for r in rows}), 220.0 + 15.0 * np.arange(50))
    assert (tmp_path / "sweep.png").stat().st_size > 0


@pytest.mark.parametrize("argv, message", [
    (["point"], "no pipelines"),
    (["line4", "--ranges", "200:3000:100"], "beyond the record"),
    (["NEGATIVE_RADIUS"], "radius"),
    (["line4", "--ranges", "300:200:10"], "START"),
])
def test_bad_input_is_one_line(tmp_path, capsys, argv, message):
    if argv[0] == "NEGATIVE_RADIUS":       # Line 4 with pipeline A's radius made negative
        text = (importlib.resources.files("clbeam.sim.scenes") / "line4.toml").read_text()
        scene = tmp_path / "bad.toml"
        scene.write_text(text.replace("radius_m = 0.11", "radius_m = -0.11", 1))
        argv = [str(scene)]
    rc = main(["detectability", argv[0], "-o", str(tmp_path / "x.csv"), *argv[1:]])
    err = capsys.readouterr().err.strip()
    assert rc == 2 and message in err and len(err.splitlines()) == 1
