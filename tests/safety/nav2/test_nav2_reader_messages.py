"""How the Nav2 parameter reader refuses a value (SR-NAV-4): one line, whole, naming the key,
the value and what is allowed, at each boundary of each kind of parameter."""

from __future__ import annotations

from fractions import Fraction

import pytest

from safety.nav2 import reader
from safety.nav2.reader import Nav2ParamsError, Section, nearest_float32, node_parameters, shown

CODE = ["safety/nav2/reader.py"]
F = Fraction


def _refused(call: object, message: str) -> None:
    assert callable(call)
    with pytest.raises(Nav2ParamsError) as caught:
        call()
    assert str(caught.value) == message


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_long_value_is_shown_cut_to_sixty_characters() -> None:
    assert reader._MAX_SHOWN == 60
    fits = "x" * 58  # repr adds the two quotes: 60 characters
    assert shown(fits) == repr(fits)
    cut = shown("x" * 59)
    assert cut == "'" + "x" * 56 + "..."
    assert len(cut) == 60


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_numbers_are_refused_outside_their_range_and_accepted_on_its_closed_ends() -> None:
    s = Section({"v": 4, "w": 0, "t": True, "big": 1e5}, "node.Zone")
    assert s.number("v", high=F(4)) == 4
    assert s.number("w", low=F(0)) == 0
    assert s.number("missing", F(7)) == 7
    _refused(lambda: s.number("v", high=F(3)), "node.Zone.v = 4: allowed: a number in [-10000, 3]")
    _refused(
        lambda: s.number("w", low=F(0), low_open=True),
        "node.Zone.w = 0: allowed: a number in (0, 10000]",
    )
    _refused(lambda: s.number("t"), "node.Zone.t = True: allowed: a number in [-10000, 10000]")
    _refused(
        lambda: s.number("big"), "node.Zone.big = 100000.0: allowed: a number in [-10000, 10000]"
    )


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_integers_strings_choices_and_sections_name_what_is_allowed() -> None:
    s = Section({"n": 1, "z": 0, "b": True, "s": 3, "c": "x", "p": 3, "ok": "yes"}, "node")
    assert s.integer("n", 5, low=1) == 1
    assert s.integer("missing", 5, low=1) == 5
    _refused(lambda: s.integer("z", 5, low=1), "node.z = 0: allowed: an integer >= 1")
    _refused(lambda: s.integer("b", 5, low=0), "node.b = True: allowed: an integer >= 0")
    assert s.string("ok") == "yes"
    assert s.string("missing", "d") == "d"
    _refused(lambda: s.string("s"), "node.s = 3: allowed: a string")
    _refused(lambda: s.choice("c", ("a", "b")), "node.c = 'x': allowed: a | b")
    _refused(
        lambda: s.section("p", required=False), "node.p = 3: allowed: a mapping of its parameters"
    )
    assert s.section("missing", required=False) is None


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_list_of_names_is_non_empty_distinct_strings() -> None:
    s = Section({"ok": ["a", "b"], "empty": [""], "number": [3], "twice": ["a", "a"]}, "node")
    allowed = "allowed: a list of distinct names"
    assert s.names("ok", required=True) == ("a", "b")
    assert s.names("missing", required=False) == ()
    _refused(lambda: s.names("missing", required=True), f"node.missing = None: {allowed}")
    _refused(lambda: s.names("empty", required=False), f"node.empty = ['']: {allowed}")
    _refused(lambda: s.names("number", required=False), f"node.number = [3]: {allowed}")
    _refused(lambda: s.names("twice", required=False), f"node.twice = ['a', 'a']: {allowed}")


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_bad_element_of_a_triple_names_the_triple() -> None:
    s = Section({"max_velocity": [0.5, "x", 1.0]}, "velocity_smoother")
    _refused(
        lambda: s.triple("max_velocity"),
        "velocity_smoother.max_velocity = 'x': allowed: a number in [-10000, 10000]",
    )


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_node_is_found_under_its_namespace_and_only_there() -> None:
    params = {"ros__parameters": {"a": 1}}
    found = node_parameters({"/robot1/collision_monitor": params}, "collision_monitor")
    assert found is not None
    assert found.data == {"a": 1}
    assert node_parameters({"my_collision_monitor": params}, "collision_monitor") is None
    _refused(
        lambda: node_parameters({"collision_monitor": 3}, "collision_monitor"),
        "collision_monitor = 3: expected a mapping with a `ros__parameters:` mapping",
    )


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_a_yaml_error_names_its_line_and_column_and_a_list_document_is_refused() -> None:
    _refused(
        lambda: reader.parse_yaml("a: 1\nb: [\n", "f.yaml"),
        "f.yaml: not valid YAML: expected the node content, but found '<stream end>' "
        "(line 3, column 1)",
    )
    _refused(
        lambda: reader.parse_yaml("- 1\n", "f.yaml"),
        "f.yaml: the document is list: expected a mapping of node names to `ros__parameters:`",
    )


@pytest.mark.requirement("SR-NAV-4", kind="example", code=CODE)
def test_single_precision_rounding_is_to_the_nearest_even_when_a_double_would_tie() -> None:
    """1 + 1.5 * 2^-23 lies between the float32 neighbours 1 + 2^-23 (odd) and 1 + 2^-22
    (even). A hair below it, the value is nearer the odd one, though rounding through a double
    first lands on the tie and then on the even one; a hair above, nearer the even one."""
    odd, even = F(1) + F(1, 2**23), F(1) + F(2, 2**23)
    tie = (odd + even) / 2
    hair = F(1, 2**100)
    assert nearest_float32(tie - hair) == odd
    assert nearest_float32(tie + hair) == even
    assert nearest_float32(tie) == even
    assert nearest_float32(-(tie - hair)) == -odd
