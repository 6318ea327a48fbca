"""The mutation-testing bookkeeping: test selection, stable mutant keys, the cache's freshness
and the score (SR-EVD-5), on a small tree built in a temporary folder."""

from __future__ import annotations

from pathlib import Path

import pytest

from evidence.mutation import (
    RESULTS_DIR,
    Equivalent,
    ModuleResult,
    MutantOutcome,
    Target,
    code_sha256,
    describe,
    digest,
    left_out,
    load_equivalents,
    load_results,
    mutant_key,
    select_tests,
    write_result,
)
from evidence.mutation_run import (
    TIMEOUT_CONSTANT_S,
    _failing_before,
    _function_name,
    _mutmut_config,
    main,
)
from evidence.mutation_targets import LEFT_OUT_TESTS

CODE = ["evidence/mutation.py", "evidence/mutation_run.py"]
TARGET = Target("pkg/sub/mod.py", "safety")


def _tree(root: Path) -> None:
    files = {
        "pkg/sub/mod.py": "def f(x):\n    return x < 1\n",
        "tests/test_imports.py": "from pkg.sub.mod import f\n",
        "tests/deep/test_parent.py": "from pkg.sub import mod\n",
        "tests/test_plain.py": "import pkg.sub.mod\n",
        "properties/test_names.py": 'CODE = ["pkg/sub/mod.py"]\n',
        "properties/test_other.py": "import pkg.sub\nTEXT = 'pkg/sub/mod.py is mentioned'\n",
        "properties/helper.py": "from pkg.sub.mod import f\n",
    }
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_a_module_is_claimed_by_the_test_files_that_import_it_or_name_its_path(
    tmp_path: Path,
) -> None:
    _tree(tmp_path)
    assert select_tests(TARGET, tmp_path) == [
        "tests/deep/test_parent.py",
        "tests/test_imports.py",
        "tests/test_plain.py",
        "properties/test_names.py",
    ]


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_the_key_names_only_the_changed_lines_and_survives_edits_elsewhere() -> None:
    before = "def _(a, b):\n    c = a + b\n    return c < 1\n"
    after = "def _(a, b):\n    c = a + b\n    return c <= 1\n"
    key = mutant_key("m.py", "f", before, after)
    assert key == "m.py | f | return c < 1 -> return c <= 1"
    moved = "def _(a, b):\n    # a comment\n\n    c  =  a + b\n    return   c < 1\n"
    moved_after = "def _(a, b):\n    # a comment\n\n    c  =  a + b\n    return   c <= 1\n"
    assert mutant_key("m.py", "f", moved, moved_after) == key
    assert mutant_key("m.py", "f", before, before) == "m.py | f |  -> "


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_the_code_hash_ignores_documentation_and_sees_every_change_of_code() -> None:
    base = code_sha256(
        b'"""M."""\nclass C:\n    """C."""\n    def f(self, x):\n        return x < "a"\n'
    )
    same = (
        b"# a comment\nclass C:\n\n    def f(self, x):  # why\n"
        b'        """F, in metres."""\n        return (x < \'a\')\n'
    )
    assert code_sha256(same) == base
    for changed in (
        b'class C:\n    def f(self, x):\n        return x <= "a"\n',
        b'class C:\n    def f(self, x):\n        return x < "b"\n',
        b'class C:\n    def f(self, y):\n        return y < "a"\n',
        b'class C:\n    def f(self, x):\n        "a"\n        "b"\n        return x < "a"\n',
    ):
        assert code_sha256(changed) != base, changed
    # A body that was only a docstring is a pass; source that does not parse is its bytes.
    assert code_sha256(b'def f():\n    """Doc."""\n') == code_sha256(b"def f():\n    pass\n")
    assert code_sha256(b"def f(:\n") != code_sha256(b"def f( :\n")


def _write_result(root: Path, target: Target, statuses: list[str]) -> None:
    mutants = [
        MutantOutcome("f", f"{target.path} | f | k{i}", status)  # type: ignore[arg-type]
        for i, status in enumerate(statuses)
    ]
    write_result(root / RESULTS_DIR, target, digest(target, root), mutants, 1.0, ["t::x"])


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_a_cached_result_is_stale_once_the_module_or_a_selected_test_changes(
    tmp_path: Path,
) -> None:
    _tree(tmp_path)
    (missing,) = load_results(tmp_path, targets=[TARGET])
    assert (missing.state, missing.why) == (
        "missing",
        "not measured: no safety/mutation/pkg__sub__mod.json",
    )
    _write_result(tmp_path, TARGET, ["killed", "survived"])
    (fresh,) = load_results(tmp_path, targets=[TARGET])
    assert (fresh.state, fresh.why) == ("fresh", "")
    assert [(m.function, m.key, m.status) for m in fresh.mutants] == [
        ("f", "pkg/sub/mod.py | f | k0", "killed"),
        ("f", "pkg/sub/mod.py | f | k1", "survived"),
    ]
    assert fresh.failing_before == ["t::x"]
    assert describe(fresh, {}) == (
        "pkg/sub/mod.py: 1 of 2 killed (50.0 %; 0 equivalent, 0 pending review, 1 survived, "
        "0 reached by no test) [fresh]"
    )
    # Documentation is not code: a comment, a docstring and layout keep the result fresh.
    (tmp_path / "tests/test_plain.py").write_text('"""Plain."""\nimport  pkg.sub.mod  # edited\n')
    (tmp_path / "pkg/sub/mod.py").write_text('def f(x):\n    """Doc."""\n\n    return (x < 1)\n')
    assert load_results(tmp_path, targets=[TARGET])[0].state == "fresh"
    (tmp_path / "tests/test_plain.py").write_text("import pkg.sub.mod as m\n")
    (stale,) = load_results(tmp_path, targets=[TARGET])
    assert stale.state == "stale"
    assert stale.why == "changed tests: tests/test_plain.py"
    (tmp_path / "tests/test_new.py").write_text("from pkg.sub import mod\n")
    (tmp_path / "pkg/sub/mod.py").write_text("def f(x):\n    return x <= 1\n")
    (stale,) = load_results(tmp_path, targets=[TARGET])
    assert stale.why == (
        "pkg/sub/mod.py changed; changed tests: tests/test_plain.py; new tests: tests/test_new.py"
    )
    _write_result(tmp_path, TARGET, ["killed"])
    assert load_results(tmp_path, targets=[TARGET])[0].state == "fresh"


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_only_reviewed_equivalents_leave_the_denominator() -> None:
    statuses = ["killed", "timeout", "survived", "survived", "no tests", "killed"]
    result = ModuleResult(
        TARGET,
        "fresh",
        mutants=[MutantOutcome("f", f"k{i}", s) for i, s in enumerate(statuses)],  # type: ignore[arg-type]
    )
    assert result.score({}) == pytest.approx(3 / 6)
    reviewed = {"k2": Equivalent("k2", "the branch is unreachable", "A. Person")}
    assert result.score(reviewed) == pytest.approx(3 / 5)
    pending = {"k3": Equivalent("k3", "the branch is unreachable", "")}
    assert result.score(pending) == pytest.approx(3 / 6)
    counts = result.counts(reviewed | pending)
    assert counts == {
        "total": 6,
        "killed": 2,
        "timeout": 1,
        "survived": 1,
        "no tests": 1,
        "equivalent": 1,
        "pending": 1,
        "other": 0,
    }
    assert [m.key for m in result.survivors(reviewed | pending)] == ["k3", "k4"]


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_the_equivalents_file_needs_a_reason_for_every_entry(tmp_path: Path) -> None:
    file = tmp_path / "eq.toml"
    file.write_text(
        '[equivalent]\n"m.py | f | a -> b" = { reason = "why", reviewed_by = "A. Person" }\n'
    )
    assert load_equivalents(file) == {
        "m.py | f | a -> b": Equivalent("m.py | f | a -> b", "why", "A. Person")
    }
    file.write_text('[equivalent]\n"m.py | f | a -> b" = { reason = "" }\n')
    with pytest.raises(ValueError, match="needs its reason"):
        load_equivalents(file)
    file.write_text('[equivalent]\n"k" = { reason = "why", by = "x" }\n')
    with pytest.raises(ValueError, match="expected"):
        load_equivalents(file)
    assert load_equivalents(tmp_path / "absent.toml") == {}


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_campaigns_and_measurements_are_left_out_of_the_mutant_runs(tmp_path: Path) -> None:
    (tmp_path / "tests").mkdir()
    (tmp_path / "tests/test_kinds.py").write_text(
        "import pytest\n"
        "@pytest.mark.requirement('SR-A-1', kind='campaign')\n"
        "def test_long(): ...\n"
        "@pytest.mark.requirement('SR-A-1', kind='measurement', code=['m.py'])\n"
        "def test_timed(): ...\n"
        "@pytest.mark.requirement('SR-A-1', kind='example')\n"
        "def test_example(): ...\n"
        "@pytest.mark.requirement('SR-A-1')\n"
        "def test_inferred(): ...\n"
        "def test_plain(): ...\n"
        "def test_on_a_cluster(client): ...\n"
        "def test_with_a_tmp_path(tmp_path): ...\n"
    )
    assert left_out(["tests/test_kinds.py"], tmp_path) == [
        "tests/test_kinds.py::test_long",
        "tests/test_kinds.py::test_timed",
        "tests/test_kinds.py::test_on_a_cluster",
    ]
    assert digest(Target("tests/test_kinds.py", "safety"), tmp_path, ["tests/test_kinds.py"])[
        "pytest_args"
    ][-6:] == [
        "--deselect",
        "tests/test_kinds.py::test_long",
        "--deselect",
        "tests/test_kinds.py::test_timed",
        "--deselect",
        "tests/test_kinds.py::test_on_a_cluster",
    ]


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_mutmut_names_map_to_the_function_and_method_names() -> None:
    assert _function_name("x_clock") == "clock"
    assert _function_name("xǁMonitorVerdictǁslow") == "MonitorVerdict.slow"


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_tests_failing_before_mutation_are_found_and_left_out(tmp_path: Path) -> None:
    (tmp_path / "test_base.py").write_text(
        "def test_green():\n    pass\n\ndef test_red():\n    assert 1 == 2\n"
    )
    log = tmp_path / "log.txt"
    failing = _failing_before(tmp_path, ["test_base.py"], ["-p", "no:cacheprovider"], log)
    assert failing == ["test_base.py::test_red"]
    assert "clean run" in log.read_text()


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_the_command_line_refuses_bad_input_in_one_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["--root", str(tmp_path / "absent"), "status"]) == 2
    assert "not a safecase checkout" in capsys.readouterr().err
    (tmp_path / "safety").mkdir()
    assert main(["--root", str(tmp_path), "survivors", "--only", "("]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ")
    assert err.count("\n") == 1
    (tmp_path / "safety/mutation-equivalents.toml").write_text('[equivalent]\n"k" = {}\n')
    assert main(["--root", str(tmp_path), "status"]) == 2
    assert "needs its reason" in capsys.readouterr().err


def test_mutmut_reads_the_timeout_room_left_for_fixtures(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The CPU limit's constant reaches mutmut (its own reader of pyproject.toml): mutmut times
    only test bodies, so without it a mutant could be counted killed for its fixtures' time."""
    from mutmut.configuration import _config_reader

    target = Target("safety/model/governor.py", "safety")
    text = _mutmut_config(target, ["tests/test_a.py"], ["-q"])
    (tmp_path / "pyproject.toml").write_text(text, encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    read = _config_reader()
    assert read("timeout_constant", 1.0) == TIMEOUT_CONSTANT_S >= 10.0
    assert read("only_mutate", []) == [target.path]


@pytest.mark.requirement("SR-EVD-5", kind="example", code=CODE)
def test_tests_that_start_a_cluster_in_process_are_left_out_by_name(tmp_path: Path) -> None:
    """Listed in LEFT_OUT_TESTS: left out where their file is selected, and only they."""
    listed = sorted(LEFT_OUT_TESTS)
    for node_id in listed:
        name, test = node_id.split("::")
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        with (tmp_path / name).open("a", encoding="utf-8") as file:
            file.write(f"def {test}(tmp_path): ...\ndef {test}_too(tmp_path): ...\n")
    files = sorted({node_id.split("::")[0] for node_id in listed})
    assert sorted(left_out(files, tmp_path)) == listed
    # Every listed test exists where it is said to be, so the list cannot go stale unseen.
    for node_id in listed:
        name, test = node_id.split("::")
        assert f"def {test}(" in (Path(__file__).resolve().parents[2] / name).read_text()
