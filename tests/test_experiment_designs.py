"""Designs: the TOML loader at the edge, the trial plan's orders, and the older commands as designs."""

import csv
import itertools
import json
from collections import Counter

import pytest
from conftest import assert_one_line_error, run_cli

from ultraglide.experiment import (
    Block,
    Condition,
    Design,
    ExperimentError,
    Stimulus,
    design_from_dict,
    design_from_toml,
    plan,
    to_toml,
)
from ultraglide.experiment.design import latin_square_row

SIM = "sim:threshold=0.08,slope=3,lapse=0.02"


def two_conditions(task="afc", order="random", **block):
    stimuli = {"a": Stimulus("a", "grating-1mm", contrast=0.3), "b": Stimulus("b", "grating-2mm", contrast=0.3)}
    return Design("t", stimuli,
                  {"ab": Condition("ab", "a", "b", levels=(0.1, 0.2)), "ba": Condition("ba", "b", "a", levels=(0.3,))},
                  (Block("main", task, ("ab", "ba"), **block),), seed=5, order=order)


def test_forced_choice_targets_take_every_position_once_per_cycle_and_the_seed_fixes_them():
    trials = plan(two_conditions("afc", intervals=3, repeats=9))
    for name in ("ab", "ba"):
        targets = [t.target for t in trials if t.condition == name]
        assert len(targets) == 9
        for cycle in range(3):
            assert sorted(targets[3 * cycle:3 * cycle + 3]) == [0, 1, 2]
        # the odd zone holds A (the condition's stimulus), the others B
        for t in (t for t in trials if t.condition == name):
            expected = [name[0] if zone == t.target else name[1] for zone in range(3)]
            assert list(t.zones) == expected
    assert [t.as_dict() for t in trials] == [t.as_dict() for t in plan(two_conditions("afc", intervals=3, repeats=9))]
    other = Design(**{**two_conditions("afc", intervals=3, repeats=9).__dict__, "seed": 6})
    assert [t.target for t in plan(other)] != [t.target for t in trials]


def test_random_order_interleaves_conditions_and_blocked_keeps_them_apart():
    interleaved = [t.condition for t in plan(two_conditions("staircase", trials=20))]
    assert Counter(interleaved) == {"ab": 20, "ba": 20}
    switches = sum(a != b for a, b in itertools.pairwise(interleaved))
    assert 10 < switches < 39  # a random sequence of 40 switches about 20 times; never kept apart
    blocked = [t.condition for t in plan(two_conditions("staircase", order="blocked", trials=20))]
    assert blocked == ["ab"] * 20 + ["ba"] * 20


def test_same_different_shows_each_pair_repeats_times():
    trials = plan(two_conditions("same_different", repeats=3))
    for name, (a, b) in (("ab", ("a", "b")), ("ba", ("b", "a"))):
        pairs = Counter(t.zones for t in trials if t.condition == name)
        assert pairs == {(a, a): 3, (b, b): 3, (a, b): 3, (b, a): 3}
        assert all(t.target == int(t.zones[0] != t.zones[1]) for t in trials)


def test_constant_stimuli_levels_come_each_repeats_times_and_practice_and_breaks_are_marked():
    trials = plan(two_conditions("constant", intervals=2, repeats=4, practice=3, break_every=5))
    practice = [t for t in trials if t.practice]
    assert len(practice) == 3 and trials[:3] == practice
    own = [t for t in trials if not t.practice]
    assert Counter((t.condition, t.level) for t in own) == {("ab", 0.1): 4, ("ab", 0.2): 4, ("ba", 0.3): 4}
    assert [t.number for t in trials if t.break_before] == [6, 11]


def test_counterbalanced_block_orders_are_a_balanced_latin_square():
    for n in (2, 3, 4, 5):
        rows = [latin_square_row(n, r) for r in range(2 * n if n % 2 else n)]
        assert all(sorted(row) == list(range(n)) for row in rows)
        firsts = Counter(row[0] for row in rows)
        assert set(firsts.values()) == {len(rows) // n}  # each block first equally often
        pairs = Counter(pair for row in rows for pair in itertools.pairwise(row))
        assert len(pairs) == n * (n - 1) and len(set(pairs.values())) == 1  # each follows each equally often
    design = Design("cb", {"a": Stimulus("a", "grating-1mm")}, {"c": Condition("c", "a")},
                    tuple(Block(f"b{i}", "rating", ("c",), repeats=1) for i in range(3)), order="counterbalanced")
    orders = {participant: [t.block for t in plan(design, participant)] for participant in ("P1", "P2", "P07")}
    assert orders["P1"] != orders["P2"] and orders["P07"] == orders["P1"]  # 6 rows for 3 blocks: 7 = 1 mod 6


def test_toml_round_trip_gives_the_same_design():
    design = two_conditions("rating", repeats=2, labels=("un", "deux", "trois", "quatre", "cinq", "six", "sept"),
                            question="Quelle rugosité ?")
    assert design_from_toml(to_toml(design)) == design
    worded = Design(**{**design.__dict__, "words": {"keys_rating": "Touches : 1–{last}.", "ok": "Valider",
                                                     "end": "C'est fini. Merci « {{vraiment}} »."}})
    again = design_from_toml(to_toml(worded))
    assert again == worded and again.words == worded.words
    assert again.word("keys_rating", last=7) == "Touches : 1–7." and again.word("keys_pair") == (
        "Keys: S for same, D for different.")  # the English default where the design says nothing
    assert again.word("end") == "C'est fini. Merci « {vraiment} »."


@pytest.mark.parametrize(("tables", "words"), [
    ({"stimuli": {"a": {"texture": "grating-1mm", "contrast": "high"}}}, "stimuli.a.contrast: must be a number"),
    ({"stimuli": {"a": {"texture": "grating-1mm", "colour": 1}}}, "stimuli.a: unknown key 'colour'"),
    ({"conditions": [{"name": "c", "stimulus": "nope"}]}, "conditions.c.stimulus: no stimulus named 'nope'"),
    ({"blocks": [{"task": "ranking", "conditions": ["c"]}]}, "blocks[0].task: must be one of"),
    ({"blocks": [{"task": "afc", "conditions": ["c"]}]}, "compares two stimuli"),
    ({"blocks": [{"task": "rating", "conditions": ["c"], "labels": ["a", "b"]}]}, "takes 7 labels"),
    ({"blocks": [{"task": "constant", "conditions": ["c"]}]}, "conditions.c.levels"),
    ({"blocks": [{"task": "magnitude", "conditions": ["c"]}]}, "modulus_stimulus"),
    ({"experiment": {"order": "sideways"}}, "experiment.order: must be one of random, blocked, counterbalanced"),
    ({"blocks": [{"task": "staircase", "conditions": ["c"], "trials": 0}]}, "blocks[0].trials: must be a whole"),
    ({"words": {"keys_choice": "Touches : 1–{n}"}}, "words.keys_choice: {n} is not a placeholder it takes; it takes "
                                                   "{last}"),
    ({"words": {"keys_pair": "S : {last}"}}, "words.keys_pair: {last} is not a placeholder it takes; it takes none"),
    ({"words": {"progress": "Essai {trial:03d}"}}, "words.progress: {trial:03d} is not a placeholder it takes"),
    ({"words": {"end": "Merci {"}}, "words.end: a brace without its pair"),
    ({"words": {"colour": "rouge"}}, "words.colour: no such words; a design's [words] are progress, keys_choice"),
    ({"words": {"ok": 3}}, "words.ok: must be printable text"),
    ({"words": "ok"}, "words: must be a table"),
    ({"experiment": {"language": "French"}}, "experiment.language: must be a language tag such as en, fr or pt-BR"),
])
def test_bad_designs_are_refused_naming_the_key(tables, words):
    base = {"stimuli": {"a": {"texture": "grating-1mm"}}, "conditions": [{"name": "c", "stimulus": "a"}],
            "blocks": [{"task": "rating", "conditions": ["c"]}]}
    with pytest.raises(ExperimentError) as error:
        design_from_dict({**base, **tables})
    assert words in str(error.value) and "\n" not in str(error.value)


@pytest.mark.parametrize(("text", "words"), [
    ("[stimuli.a\ntexture = 1", "not TOML"),
    ("[stimuli.a]\ntexture = 'grating-1mm'\n[[conditions]]\nname = 'c'\nstimulus = 'a'\n[[blocks]]\ntask = 'rating'\n"
     "conditions = ['c']\nscale = [1, 500]", "blocks[0].scale"),
    ("[stimuli.a]\ntexture = 'no-such-texture.png'\n[[conditions]]\nname = 'c'\nstimulus = 'a'\n[[blocks]]\n"
     "task = 'rating'\nconditions = ['c']", "stimuli.a.texture: "),
    ("[stimuli.a]\ntexture = 'grating-1mm'\n[[conditions]]\nname = 'c'\nstimulus = 'a'\n[[blocks]]\ntask = 'rating'\n"
     "conditions = ['c']\n[words]\nkeys_rating = 'Touches 1–{n}'", "words.keys_rating: {n} is not a placeholder"),
])
def test_check_refuses_a_bad_design_file_in_one_line_with_status_2(tmp_path, text, words):
    path = tmp_path / "bad.toml"
    path.write_text(text, encoding="utf-8")
    result = run_cli("experiment", "check", path)
    line = assert_one_line_error(result)
    assert result.returncode == 2 and words in line and str(path) in line
    assert result.stdout == ""


def test_check_json_is_strict_json_holding_the_design_its_check_and_plan(tmp_path):
    path = tmp_path / "d.toml"
    path.write_text(to_toml(two_conditions("afc", intervals=2, repeats=4)), encoding="utf-8")
    result = run_cli("experiment", "check", path, "--json", check=True)
    document = json.loads(result.stdout, parse_constant=lambda name: pytest.fail(f"not strict JSON: {name}"))
    assert document["check"]["passed"] is True and set(document["check"]["stimuli"]) == {"a", "b"}
    assert [t["target"] for t in document["plan"]] == [t.target for t in plan(two_conditions("afc", repeats=4))]
    assert document["design"]["blocks"][0]["task"] == "afc"


def test_a_design_that_is_not_a_file_is_refused_in_one_line(tmp_path):
    result = run_cli("experiment", "check", tmp_path)
    assert result.returncode == 2 and str(tmp_path) in assert_one_line_error(result)


def read(path):
    with open(path, newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


@pytest.mark.parametrize("command", [
    ["threshold", "grating-1mm", "--method", "staircase", "--afc", "3", "--trials", "14", "--seed", "3"],
    ["threshold", "grating-1mm", "--method", "quest", "--trials", "10", "--seed", "2", "--reference", "grating-4mm"],
    ["constant", "--preset", "vezzoli2015", "--repeats", "3", "--seed", "4"],
])
def test_print_design_runs_to_the_same_trial_plan_and_answers(tmp_path, command):
    printed = run_cli("experiment", *command, "--print-design", check=True)
    assert not list(tmp_path.iterdir())  # --print-design writes nothing
    design_path = tmp_path / "design.toml"
    design_path.write_text(printed.stdout, encoding="utf-8")
    run_cli("experiment", *command, "--observer", SIM, "--out", tmp_path / "old", "--no-figures", check=True)
    run_cli("experiment", "run", design_path, "--participant", "P01", "--out", tmp_path / "new", "--observer", SIM,
            check=True)
    old, new = read(tmp_path / "old" / "trials.csv"), read(tmp_path / "new" / "trials.csv")
    assert len(old) == len(new) > 0
    for before, after in zip(old, new, strict=True):
        assert float(before["level"]) == float(after["level"])
        assert (before["target"], before["response"], before["correct"]) == (
            after["target"], after["response"], after["correct"])
        assert before["rendered_contrast"] == (f"{float(after['delivered_contrast']):.4f}"
                                               if after["delivered_contrast"] else "")


def test_a_stopped_design_session_resumes_as_if_never_stopped(tmp_path):
    path = tmp_path / "stairs.toml"
    path.write_text(to_toml(Design(
        "resume", {"a": Stimulus("a", "grating-1mm"), "b": Stimulus("b", "grating-4mm")},
        {"a": Condition("a", "a"), "b": Condition("b", "b")},
        (Block("s", "staircase", ("a", "b"), trials=8, practice=2), Block("r", "rating", ("a",), repeats=3)),
        seed=9)), encoding="utf-8")
    whole, cut = tmp_path / "whole", tmp_path / "cut"
    common = ["experiment", "run", path, "--participant", "P04", "--observer", SIM]
    run_cli(*common, "--out", whole, check=True)
    run_cli(*common, "--out", cut, check=True)
    lines = (cut / "trials.csv").read_text(encoding="utf-8").splitlines(keepends=True)
    # stopped during trial 9: eight rows logged and half of the ninth
    (cut / "trials.csv").write_text("".join(lines[:9]) + lines[9][:20], encoding="utf-8")
    refused = run_cli(*common, "--out", cut)
    assert "--resume" in assert_one_line_error(refused)
    other = run_cli("experiment", "run", path, "--participant", "P05", "--observer", SIM, "--out", cut, "--resume")
    assert "another design, participant or session" in assert_one_line_error(other)
    run_cli(*common, "--out", cut, "--resume", check=True)
    before, after = read(whole / "trials.csv"), read(cut / "trials.csv")
    assert len(before) == len(after) == 2 + 16 + 3
    for a, b in zip(before, after, strict=True):
        assert {k: v for k, v in a.items() if k != "time_utc"} == {k: v for k, v in b.items() if k != "time_utc"}
    assert json.loads((cut / "summary.json").read_text())["blocks"] == json.loads(
        (whole / "summary.json").read_text())["blocks"]
