"""evigrid.mass: the numbers of `evigrid mass`, and an exception naming the input for bad ones."""

from __future__ import annotations

import errno
import json
import math
from pathlib import Path
from typing import Any, Dict, List, Tuple

import pytest

import evigrid
from evigrid import mass

# The shared vectors print 12 decimals.
TOLERANCE = 1e-9

TABLE_I = [
    {"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 0.2}, {"set": ["b"], "m": 0.6}, {"set": ["a", "b"], "m": 0.2}]},
    {"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 0.7}, {"set": ["b"], "m": 0.1}, {"set": ["a", "b"], "m": 0.2}]},
]


def by_set(entries: List[Dict[str, Any]], key: str) -> Dict[Tuple[str, ...], float]:
    return {tuple(entry["set"]): entry[key] for entry in entries}


def close(got: Dict[Any, float], want: Dict[Any, float]) -> bool:
    keys = set(got) | set(want)
    return all(math.isclose(got.get(k, 0.0), want.get(k, 0.0), abs_tol=TOLERANCE) for k in keys)


def write(folder: Path, name: str, value: Any) -> str:
    path = folder / name
    path.write_text(json.dumps(value), encoding="utf-8")
    return str(path)


RULE_OF_OP = {
    "conjunctive": "conjunctive",
    "dempster": "dempster",
    "disjunctive": "disjunctive",
    "yager": "yager",
    "dubois_prade": "dubois-prade",
}


def test_every_shared_vector_gives_the_numbers_of_the_command(vectors, cli, tmp_path):
    ops = set()
    for index, vector in enumerate(vectors):
        op = vector["op"]
        ops.add(op)
        inputs = [{"frame": vector["frame"], "mass": focal} for focal in vector["inputs"]]
        files = [write(tmp_path, f"v{index}-{k}.json", m) for k, m in enumerate(inputs)]
        where = f"vector {index} ({op}, {vector['source']})"
        if op in RULE_OF_OP:
            rule = RULE_OF_OP[op]
            got = mass.combine(inputs, rule=rule)
            assert got == cli.json("mass", "combine", "--rule", rule, "--json", *files), where
            assert close(by_set(got["mass"], "m"), by_set(vector["expected"], "m")), where
        elif op in ("discount", "contextual_discount"):
            if op == "discount":
                alpha = vector["params"]["alpha"]
                got = mass.discount(inputs[0], alpha)
                args = ["--alpha", repr(alpha)]
            else:
                contexts = [(tuple(c["set"]), c["alpha"]) for c in vector["params"]["contexts"]]
                got = mass.discount(inputs[0], contexts=contexts)
                args = [a for names, rate in contexts for a in ("--context", f"{'+'.join(names)}={rate!r}")]
            assert got == cli.json("mass", "discount", *args, "--json", files[0]), where
            assert close(by_set(got["mass"], "m"), by_set(vector["expected"], "m")), where
        elif op == "pignistic":
            got = mass.pignistic(inputs[0])
            want = cli.json("mass", "pignistic", "--json", files[0])
            assert list(got.items()) == list(want["betp"].items()), where
            assert close(got, vector["expected_singletons"]), where
        elif op == "transforms":
            for name in mass.FUNCTIONS:
                got = mass.transform(inputs[0], name)
                want = cli.json("mass", "transform", "--to", name, "--json", files[0])
                assert list(got.items()) == list(by_set(want[name], "v").items()), f"{where}: {name}"
                assert close(got, by_set(vector[f"expected_{name}"], "v")), f"{where}: {name}"
        else:
            pytest.fail(f"{where}: unknown op {op}")
    # Every operation of the calculator is exercised by the shared vectors.
    assert set(RULE_OF_OP) | {"discount", "contextual_discount", "pignistic", "transforms"} <= ops


def test_class_rate_discounting_by_hand_and_as_the_command(cli, tmp_path):
    m = {"frame": ["F", "M"], "mass": {"F": 0.5, "M": 0.5}}
    # {F} keeps (1 - 0.1) of 0.5 = 0.45, {M} keeps (1 - 0.5) of 0.5 = 0.25, Ω gets the 0.3 left.
    got = mass.discount(m, class_rates={"F": 0.1, "M": 0.5})
    assert close(by_set(got["mass"], "m"), {("F",): 0.45, ("M",): 0.25, ("F", "M"): 0.3})
    file = write(tmp_path, "m.json", mass.check(m))
    assert got == cli.json("mass", "discount", "--class-rate", "F=0.1", "--class-rate", "M=0.5", "--json", file)
    # With set_rate = mean, Ω's rate is (0.1 + 0.5) / 2 = 0.3, and Ω keeps its mass whatever it.
    mean = mass.discount(m, class_rates={"F": 0.1, "M": 0.5}, set_rate="mean")
    assert mean == got
    assert mean == cli.json(
        "mass", "discount", "--class-rate", "F=0.1", "--class-rate", "M=0.5", "--set-rate", "mean", "--json", file
    )


def test_yager_of_three_inputs_uses_the_n_ary_form():
    frame = ["a", "b"]
    a = {"frame": frame, "mass": {"a": 1.0}}
    b = {"frame": frame, "mass": {"b": 1.0}}
    ab = {"frame": frame, "mass": {("a", "b"): 1.0}}
    # n-ary: the only product, a ∩ b ∩ Ω = ∅, goes to Ω. Pairwise, (a ⊕ b) = Ω, then Ω ∩ Ω = Ω too;
    # so check a case where they differ: a, a, b -> n-ary Ω; pairwise (a ⊕ a) = a, a ⊕ b = Ω: same.
    assert mass.combine([a, b, ab], rule="yager") == {"frame": frame, "mass": [{"set": ["a", "b"], "m": 1.0}]}
    # Dubois–Prade, n-ary: a ∩ b ∩ Ω = ∅, so the mass goes to the union a ∪ b ∪ Ω = Ω.
    assert mass.combine([a, b, ab], rule="dubois-prade")["mass"] == [{"set": ["a", "b"], "m": 1.0}]


def test_the_input_forms_agree_and_the_output_is_a_file_the_command_reads(cli, tmp_path):
    listed = TABLE_I[0]
    mapped = {"frame": ["a", "b"], "mass": {"a": 0.2, ("b",): 0.6, frozenset({"b", "a"}): 0.2}}
    assert mass.check(mapped) == mass.check(listed) == listed
    combined = mass.combine(TABLE_I, rule="conjunctive")
    # The conflict stays on ∅, listed first: K = 0.2·0.1 + 0.6·0.7 = 0.44.
    assert combined["mass"][0]["set"] == [] and math.isclose(combined["mass"][0]["m"], 0.44)
    file = write(tmp_path, "combined.json", combined)
    assert mass.load(file) == combined
    assert mass.pignistic(combined) == cli.json("mass", "pignistic", "--json", file)["betp"]
    # Sets are returned in bitmask order whatever the order given.
    shuffled = {"frame": ["a", "b"], "mass": [{"set": ["b", "a"], "m": 0.8}, {"set": ["a"], "m": 0.2}]}
    assert [e["set"] for e in mass.check(shuffled)["mass"]] == [["a"], ["a", "b"]]


def test_a_sum_within_the_tolerance_is_accepted_and_beyond_it_is_not():
    near = {"frame": ["a", "b"], "mass": {"a": 0.2, "b": 0.8000000001}}
    assert mass.pignistic(near)["a"] == pytest.approx(0.2, abs=1e-9)
    with pytest.raises(evigrid.InputError, match=r"m: masses sum to 1\.000000002, not 1"):
        mass.pignistic({"frame": ["a", "b"], "mass": {"a": 0.2, "b": 0.800000002}})


# The bad inputs of the command's own test (crates/cli/tests/mass.rs), as dicts, with the words
# its message must hold.
BAD_MASSES = [
    ("negative mass", {"frame": ["a", "b"], "mass": [{"set": ["a"], "m": -0.2}, {"set": ["b"], "m": 1.2}]}, ["negative mass -0.2 on set [a]"]),
    ("sum off by 2e-9", {"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 0.2}, {"set": ["b"], "m": 0.800000002}]}, ["masses sum to 1.000000002, not 1"]),
    ("unknown element", {"frame": ["a", "b"], "mass": [{"set": ["c"], "m": 1}]}, ['element "c" is not in the frame {a, b}']),
    ("repeated set", {"frame": ["a", "b"], "mass": [{"set": ["a", "b"], "m": 0.5}, {"set": ["b", "a"], "m": 0.5}]}, ["set [a, b] is listed twice"]),
    ("unknown field", {"frame": ["a"], "masses": []}, ["unknown key 'masses'"]),
    ("no mass", {"frame": ["a"]}, ["no key 'mass'"]),
    ("frame repeats an element", {"frame": ["a", "a"], "mass": [{"set": ["a"], "m": 1}]}, ["bad frame", "appears twice"]),
    ("empty frame", {"frame": [], "mass": []}, ["bad frame", "at least one element"]),
    ("nine elements", {"frame": list("abcdefghi"), "mass": {"a": 1.0}}, ["bad frame", "at most 8 elements, not 9"]),
    ("NaN", {"frame": ["a"], "mass": {"a": float("nan")}}, ["mass NaN on set [a] is not finite"]),
    ("infinite", {"frame": ["a", "b"], "mass": {"a": float("inf"), "b": 0.0}}, ["mass inf on set [a] is not finite"]),
    ("mass is text", {"frame": ["a"], "mass": [{"set": ["a"], "m": "1"}]}, ["mass[0]", "'1' is not a number"]),
    ("mass is a bool", {"frame": ["a"], "mass": {"a": True}}, ["True is not a number"]),
    ("entry with more keys", {"frame": ["a"], "mass": [{"set": ["a"], "m": 1, "v": 2}]}, ["mass[0]", "expected {'set'"]),
    ("frame is a string", {"frame": "ab", "mass": {"a": 1.0}}, ["frame: expected a list of element names"]),
    ("element is a number", {"frame": ["a", 3], "mass": {"a": 1.0}}, ["element 3 is not a name"]),
    ("not a dict", [("a", 1.0)], ["expected a mass function dict, not list"]),
    ("mass is a number", {"frame": ["a"], "mass": 1.0}, ["mass: expected a list"]),
]


@pytest.mark.parametrize("case, bad, needles", BAD_MASSES, ids=[c[0] for c in BAD_MASSES])
def test_a_bad_mass_function_is_an_input_error_naming_it(case, bad, needles):
    good = {"frame": ["a", "b"], "mass": {"a": 1.0}}
    calls = [
        ("m", lambda: mass.pignistic(bad)),
        ("m", lambda: mass.transform(bad, "belief")),
        ("m", lambda: mass.discount(bad, 0.1)),
        ("masses[1]", lambda: mass.combine([good, bad], rule="conjunctive")),
    ]
    for label, call in calls:
        with pytest.raises(evigrid.InputError) as raised:
            call()
        message = str(raised.value)
        assert message.startswith(label), f"{case}: {message}"
        assert "\n" not in message, f"{case}: {message}"
        for needle in needles:
            assert needle in message, f"{case}: {needle!r} not in {message!r}"


def test_bad_files_name_the_file(tmp_path):
    cases = [
        ("malformed.json", '{"frame": ["a", "b"], "mass": [{"set": ["a"], "m": 1}', "malformed JSON"),
        ("negative.json", '{"frame": ["a", "b"], "mass": [{"set": ["a"], "m": -0.2}, {"set": ["b"], "m": 1.2}]}', "negative mass -0.2 on set [a]"),
        ("binary.json", b"\xff\xfe\x00garbage", "malformed JSON"),
    ]
    for name, text, needle in cases:
        path = tmp_path / name
        if isinstance(text, bytes):
            path.write_bytes(text)
        else:
            path.write_text(text, encoding="utf-8")
        with pytest.raises(evigrid.InputError) as raised:
            mass.load(path)
        assert str(raised.value).startswith(f"{path}: ") and needle in str(raised.value), str(raised.value)
    missing = tmp_path / "missing.json"
    with pytest.raises(evigrid.FileError) as raised:
        mass.load(missing)
    assert isinstance(raised.value, OSError) and isinstance(raised.value, evigrid.Error)
    assert str(raised.value) == f"{missing}: cannot read: No such file or directory"
    assert raised.value.errno == errno.ENOENT
    with pytest.raises(evigrid.FileError, match="cannot read"):
        mass.load(tmp_path)  # a folder
    huge = tmp_path / "huge.json"
    huge.write_bytes(b" " * (mass.MAX_FILE_BYTES + 1))
    with pytest.raises(evigrid.InputError, match="larger than 16 MiB"):
        mass.load(huge)


def test_bad_arguments_are_input_errors_naming_the_argument():
    good = {"frame": ["a", "b"], "mass": {"a": 1.0}}
    only_b = {"frame": ["a", "b"], "mass": {"b": 1.0}}
    other = {"frame": ["a", "c"], "mass": {"a": 1.0}}
    cases = [
        (lambda: mass.combine([good, other], rule="dempster"), ["masses[1]: frame {a, c} differs from frame {a, b} of masses[0]"]),
        (lambda: mass.combine([good, only_b], rule="dempster"), ["masses[0], masses[1]: total conflict"]),
        (lambda: mass.combine([good], rule="dempster"), ["1 mass function(s) given, at least two"]),
        (lambda: mass.combine(good, rule="dempster"), ["masses: expected a list"]),
        (lambda: mass.combine([good, good], rule="murphy"), ["rule 'murphy': expected one of conjunctive"]),
        (lambda: mass.discount(good, 1.5), ["alpha 1.5", "not in [0, 1]"]),
        (lambda: mass.discount(good, float("nan")), ["alpha NaN", "not in [0, 1]"]),
        (lambda: mass.discount(good), ["exactly one of alpha, contexts and class_rates"]),
        (lambda: mass.discount(good, 0.1, contexts={"a": 0.1}), ["exactly one of"]),
        (lambda: mass.discount(good, contexts={("a", "x"): 0.5}), ["contexts a+x=0.5", '"x"', "of m"]),
        (lambda: mass.discount(good, contexts={"a": "much"}), ["contexts", "'much' is not a number"]),
        (lambda: mass.discount(good, contexts={"a": 2.0}), ["contexts a=2", "not in [0, 1]"]),
        (lambda: mass.discount(good, contexts=[("a",)]), ["is not a (set, rate) pair"]),
        (lambda: mass.discount(good, class_rates={"a": 0.5}), ["class_rates: no rate for element b"]),
        (lambda: mass.discount(good, class_rates={"a": 0.5, "z": 0.1}), ['class_rates z=0.1: element "z" is not in the frame']),
        (lambda: mass.discount(good, class_rates={"a": -0.5, "b": 0.1}), ["class_rates a=-0.5", "not in [0, 1]"]),
        (lambda: mass.discount(good, 0.1, set_rate="min"), ["set_rate: applies only with class_rates"]),
        (lambda: mass.discount(good, class_rates={"a": 0.5, "b": 0.1}, set_rate="median"), ["set_rate 'median'"]),
        (lambda: mass.transform(good, "doubt"), ["to 'doubt': expected one of belief"]),
        (lambda: mass.pignistic({"frame": ["a"], "mass": {(): 1.0}}), ["m: m(∅) = 1"]),
    ]
    for call, needles in cases:
        with pytest.raises(evigrid.InputError) as raised:
            call()
        for needle in needles:
            assert needle in str(raised.value), f"{needle!r} not in {str(raised.value)!r}"


def test_the_errors_form_one_family():
    assert issubclass(evigrid.InputError, evigrid.Error) and issubclass(evigrid.InputError, ValueError)
    assert issubclass(evigrid.FileError, evigrid.Error) and issubclass(evigrid.FileError, OSError)
    assert evigrid.InputError.__module__ == "evigrid"
    assert isinstance(evigrid.__version__, str) and evigrid.__version__.count(".") == 2
