"""What sessions leave: trials.csv's columns as documented, session.json, summaries and their words."""

import csv
import json
import re
import statistics

from conftest import ROOT, run_cli

from ultraglide.experiment.columns import DESIGN_COLUMNS, THRESHOLD_COLUMNS, columns_markdown, documented_tables

SIM = "sim:threshold=0.08,slope=3,lapse=0.02"


def read(path):
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def test_the_documented_columns_are_the_codes():
    text = (ROOT / "docs" / "experiments.md").read_text(encoding="utf-8")
    tables = documented_tables(text)
    assert set(tables) == {"DESIGN_COLUMNS", "THRESHOLD_COLUMNS"}
    assert tables["DESIGN_COLUMNS"] == columns_markdown(DESIGN_COLUMNS)
    assert tables["THRESHOLD_COLUMNS"] == columns_markdown(THRESHOLD_COLUMNS)


def repeated_phrase(line: str) -> str | None:
    """A phrase of two or more words said twice in one line ("no threshold: ...: no threshold"), if any."""
    words = re.findall(r"[a-z]+", line.lower())
    for size in range(2, 5):
        grams = [tuple(words[i:i + size]) for i in range(len(words) - size + 1)]
        seen = {gram for gram in grams if grams.count(gram) > 1}
        if seen:
            return " ".join(sorted(seen)[0])
    return None


def test_a_short_session_says_why_it_has_no_threshold_once_and_summarises_its_reaction_times(tmp_path):
    result = run_cli("experiment", "threshold", "grating-1mm", "--trials", "3", "--observer", SIM, "--out", tmp_path,
                     "--no-figures", check=True)
    rows = read(tmp_path / "trials.csv")
    assert list(rows[0]) == list(THRESHOLD_COLUMNS) and len(rows) == 3
    median = statistics.median(float(r["rt_s"]) for r in rows)
    lines = result.stdout.splitlines()
    assert "no threshold: 3 trials logged, and a fit needs at least 5" in lines
    assert f"median reaction time {median:.2f} s (of 3 trials)" in lines
    assert not [line for line in lines if repeated_phrase(line)], [repeated_phrase(line) for line in lines]
    saved = json.loads((tmp_path / "result.json").read_text())
    assert saved["rt_s_median"] == statistics.median(float(r["rt_s"]) for r in rows) and saved["rt_s_count"] == 3


def test_a_design_session_writes_rows_with_factor_columns_its_metadata_and_summary(tmp_path):
    design = tmp_path / "d.toml"
    design.write_text("""
[experiment]
name = "factor columns"
seed = 2
[stimuli.a]
texture = "grating-1mm"
contrast = 0.3
[stimuli.b]
texture = "grating-2mm"
contrast = 0.3
[[conditions]]
name = "ab"
a = "a"
b = "b"
factors = { spacing = "1 vs 2", size_mm = 40 }
[[blocks]]
name = "main"
task = "afc"
conditions = ["ab"]
repeats = 6
practice = 1
""", encoding="utf-8")
    out = tmp_path / "out"
    result = run_cli("experiment", "run", design, "--participant", "P05", "--out", out, "--observer",
                     "sim:threshold=0.01,slope=2", check=True)
    rows = read(out / "trials.csv")
    columns = list(DESIGN_COLUMNS)
    at = columns.index("condition") + 1
    assert list(rows[0]) == columns[:at] + ["size_mm", "spacing"] + columns[at:]
    assert len(rows) == 7 and [r["practice"] for r in rows] == ["1"] + ["0"] * 6
    assert {(r["spacing"], r["size_mm"], r["participant"]) for r in rows} == {("1 vs 2", "40.0", "P05")}
    for row in rows:
        zones = row["stimuli"].split(" | ")
        assert zones[int(row["target"]) - 1] == "a" and zones.count("a") == 1
        assert row["correct"] == str(int(row["response"] == row["target"]))
    session = json.loads((out / "session.json").read_text())
    assert session["status"] == "complete" and session["participant"] == "P05" and session["trials_logged"] == 7
    assert session["design"]["conditions"][0]["factors"] == {"spacing": "1 vs 2", "size_mm": 40.0}
    assert "[stimuli.a]" in session["design_toml"]
    assert session["rig"]["profile"]["name"] == "sim-plate" and session["rig"]["model"]["spec"] == "stretched"
    assert session["versions"]["numpy"] and session["stimulus_check"]["passed"] is True
    figures = session["stimulus_check"]["stimuli"]["a"]
    assert float(rows[0]["delivered_contrast"]) == round(figures["delivered_contrast"], 4)
    summary = json.loads((out / "summary.json").read_text())
    main = [r for r in rows if r["practice"] == "0"]
    condition = summary["blocks"][0]["conditions"][0]
    assert condition["trials"] == 6 and condition["positive"] == sum(int(r["correct"]) for r in main)
    assert summary["rt_s_median"] == statistics.median(float(r["rt_s"]) for r in rows)
    assert f"{condition['positive']} of 6 correct" in result.stdout
    assert not [line for line in result.stdout.splitlines() if repeated_phrase(line)]
