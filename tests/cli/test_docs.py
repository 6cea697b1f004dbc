"""``clbeam docs``, and every page the help texts, the README and the docs name: it exists and prints."""

import argparse
import re
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from clbeam.cli.main import COMMANDS, build_parser, main
from clbeam.io.schema import PING_VARIABLES

ROOT = Path(__file__).resolve().parents[2]
DOCS = ROOT / "docs"
#: a page named in text: "clbeam docs TOPIC" or a path docs/NAME.md
NAMED = re.compile(r"clbeam docs ([a-z][a-z0-9_-]*)|docs/([A-Za-z0-9_.-]+\.md)")


def parser_texts():
    """Every description, help text and group title of the parser and its subcommands."""
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    out = []
    for p in (parser, *sub.choices.values()):
        out += [p.description or ""] + [g.title or "" for g in p._action_groups]
        out += [a.help for a in p._actions if isinstance(a.help, str)]
    out += [c.HELP for c in COMMANDS]
    return out


def named_topics(texts):
    return {m.group(1) or m.group(2)[:-3] for t in texts for m in NAMED.finditer(t)}


def run_docs(*argv):
    return subprocess.run([sys.executable, "-m", "clbeam", "docs", *argv], capture_output=True, text=True, cwd=ROOT)


def test_every_page_the_help_texts_name_is_a_topic_that_prints_its_file():
    topics = named_topics(parser_texts())
    assert {"ping-format", "survey", "lines", "avo"} <= topics  # the help texts do name pages
    for topic in sorted(topics):
        r = run_docs(topic)
        assert r.returncode == 0, r.stderr
        assert r.stdout == (DOCS / f"{topic}.md").read_text(encoding="utf-8")


def test_every_file_the_readme_and_the_docs_link_exists():
    pages = [ROOT / "README.md", *sorted(DOCS.glob("*.md"))]
    missing = []
    for page in pages:
        text = page.read_text(encoding="utf-8")
        for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", text):
            if re.match(r"[a-z]+://", target):
                continue
            if not (page.parent / target).exists():
                missing.append(f"{page.relative_to(ROOT)} -> {target}")
        for m in NAMED.finditer(text):
            if not (DOCS / f"{m.group(1) or m.group(2)[:-3]}.md").exists():
                missing.append(f"{page.relative_to(ROOT)} names {m.group(0)}")
    assert missing == []


def test_the_readme_names_pages_that_clbeam_docs_prints():
    topics = named_topics([(ROOT / "README.md").read_text(encoding="utf-8")])
    assert {"ping-format", "cli", "bench", "survey", "lines"} <= topics
    for topic in sorted(topics):
        assert run_docs(topic, "--path").stdout.strip() == str(DOCS / f"{topic}.md")


def test_the_list_has_every_page_with_its_first_heading(capsys):
    assert main(["docs", "-q"]) == 0
    rows = dict(line.split(None, 1) for line in capsys.readouterr().out.splitlines())
    assert set(rows) == {p.stem for p in DOCS.glob("*.md")}
    for name, heading in rows.items():
        first = next(ln for ln in (DOCS / f"{name}.md").read_text(encoding="utf-8").splitlines() if ln.startswith("#"))
        assert heading == first.lstrip("# ").strip()


@pytest.mark.parametrize("spelling", ["ping-format", "ping-format.md", "docs/ping-format.md"])
def test_a_topic_may_be_named_as_its_file(spelling, capsys):
    assert main(["docs", spelling]) == 0
    assert capsys.readouterr().out == (DOCS / "ping-format.md").read_text(encoding="utf-8")


def test_an_unknown_topic_is_one_line_and_exit_2():
    r = run_docs("nosuch")
    assert r.returncode == 2 and r.stdout == ""
    assert len(r.stderr.splitlines()) == 1
    assert r.stderr.startswith("clbeam: error: no documentation topic 'nosuch'") and "ping-format" in r.stderr


def test_the_pages_are_package_data_of_clbeam_docs():
    tool = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]
    assert "clbeam.docs" in tool["packages"]
    assert tool["package-dir"]["clbeam.docs"] == "docs"
    assert "*.md" in tool["package-data"]["clbeam.docs"]


def cli_sections():
    """docs/cli.md's text per subcommand section (### `clbeam NAME`)."""
    text = (DOCS / "cli.md").read_text(encoding="utf-8")
    parts = re.split(r"^### `clbeam ([a-z-]+)`$", text, flags=re.M)
    return dict(zip(parts[1::2], parts[2::2]))


def test_cli_md_lists_every_command_and_each_of_its_options():
    sections = cli_sections()
    parser = build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    missing = []
    for name, p in sub.choices.items():
        if name not in sections:
            missing.append(name)
            continue
        for action in p._actions:
            for opt in action.option_strings:
                if opt not in ("-h", "--help", "-q", "--quiet", "-v", "--verbose", "--debug") \
                        and f"`{opt}`" not in sections[name]:
                    missing.append(f"{name} {opt}")
    assert missing == [], "regenerate the tables: python scripts/cli_reference.py"


def markdown_table(text, first_header):
    """The rows (lists of cells) of the Markdown table whose header starts with ``first_header``."""
    lines = text.splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith(f"| {first_header} |"))
    rows = []
    for ln in lines[start + 2:]:
        if not ln.startswith("|"):
            break
        rows.append([c.strip() for c in ln.strip("|").split(" | ")])
    return rows


def test_ping_format_md_lists_every_variable_of_the_schema_with_its_units_and_whether_required():
    text = (DOCS / "ping-format.md").read_text(encoding="utf-8")
    rows = markdown_table(text, "variable") + markdown_table(text, "variable or form")
    documented = {}
    for row in rows:
        for name in re.findall(r"`([a-z_0-9]+)`", row[0]):
            documented[name] = row
    assert set(PING_VARIABLES) - set(documented) == set()
    for name, var in PING_VARIABLES.items():
        row = documented[name]
        if var.required:
            assert row[4].startswith("yes"), name
        if var.units not in ("", "1") and len(row) > 2:
            units = {"degree_north": "degree", "degree_east": "degree"}.get(var.units, var.units)
            assert units in row[2], (name, row[2])


def test_the_ping_format_example_writes_a_file_clbeam_reads(tmp_path, monkeypatch):
    from clbeam.io.pingfile import PingFile

    text = (DOCS / "ping-format.md").read_text(encoding="utf-8")
    code = re.search(r"## Writing a ping file.*?```python\n(.*?)```", text, flags=re.S).group(1)
    monkeypatch.chdir(tmp_path)
    exec(compile(code, "ping-format.md", "exec"), {})
    with PingFile(tmp_path / "pings.nc") as f:
        assert (f.n_pings, f.n_channels, f.n_samples, f.kind) == (2, 64, 4000, "raw")
        assert f.pulse.f0_hz == 2000.0 and f.pulse.f1_hz == 9000.0 and f.pulse.duration_s == 0.08
        pings = list(f)
    assert [p.roll_deg for p in pings] == [0.5, -0.3]
    np.testing.assert_allclose(np.diff(pings[0].element_pos_m[:, 1]), 3.528 / 64, rtol=1e-12)
