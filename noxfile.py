"""One session per supported Python (docs/python-versions.md).

``nox -s tests-3.12`` (or ``tests-3.11``, ``tests-3.10``) runs ``make test`` with that Python:
the Makefile builds the session's own virtual environment, ``.nox/tests-3.12``, from
requirements.lock, then runs ruff, import-linter, mypy and the pytest suite in it, writing the
evidence to ``out/test-evidence-3.12`` (on 3.10 without mypy: see TARGETS). A bare ``nox`` runs
``tests-3.11``, the Python of CI's ``make test``. ``nox -s wheels`` checks that every pin of
the lock has a wheel for each supported Python (``make lock`` runs it).

The sessions bring no environment of their own (``venv_backend="none"``): how safecase is
installed and tested is written once, in the Makefile, and nox only finds the interpreter.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import nox

PYTHONS = ("3.10", "3.11", "3.12")
DEFAULT_PYTHON = "3.11"
# Pure-Python packages published as a source archive only; every other pin must be a wheel.
SOURCE_ONLY = ("rplidar-roboticia",)


def _version_key(path: str) -> tuple[int, ...]:
    found = re.search(r"/versions/(\d+)\.(\d+)\.(\d+)", path)
    return tuple(int(part) for part in found.groups()) if found else (0,)


def interpreter(version: str) -> str:
    """The path of a working ``python<version>``: the one on PATH, else pyenv's newest.

    A pyenv shim is on PATH for every installed version but runs only the globally selected
    ones, so each candidate is asked for its version before it is used.
    """
    candidates = []
    on_path = shutil.which(f"python{version}")
    if on_path:
        candidates.append(on_path)
    pyenv_root = Path(os.environ.get("PYENV_ROOT", Path.home() / ".pyenv"))
    found = [str(p) for p in pyenv_root.glob(f"versions/{version}.*/bin/python{version}")]
    candidates += sorted(found, key=_version_key, reverse=True)
    wanted = tuple(int(part) for part in version.split("."))
    for candidate in candidates:
        probe = subprocess.run(
            [candidate, "-c", "import sys; print(*sys.version_info[:2])"],
            capture_output=True,
            text=True,
            check=False,
        )
        if probe.returncode == 0 and tuple(map(int, probe.stdout.split())) == wanted:
            return candidate
    raise RuntimeError(
        f"no working python{version} on PATH or in {pyenv_root}/versions "
        f"(install it, e.g. `pyenv install {version}`)"
    )


# mypy reads the libraries' own stubs: Python 3.10's lock has numpy 2.2, whose stubs lack the
# defaults of numpy >= 2.3 that the code is typed against, so that session runs the lint and the
# suite; the type check as Python 3.10 reads the code is CI's (python_version in pyproject.toml).
TARGETS = {"3.10": ("lint", "pytest")}


def _tests(session: nox.Session, version: str) -> None:
    try:
        python = interpreter(version)
    except RuntimeError as exc:
        session.error(str(exc))
    session.run(
        "make",
        *TARGETS.get(version, ("test",)),
        f"PYTHON={python}",
        f"VENV=.nox/tests-{version}",
        f"TEST_OUT=out/test-evidence-{version}",
        *session.posargs,
        external=True,
    )


for _version in PYTHONS:

    @nox.session(
        name=f"tests-{_version}",
        venv_backend="none",
        default=_version == DEFAULT_PYTHON,
    )
    def suite(session: nox.Session, version: str = _version) -> None:
        """`make test` on one Python, in .nox/tests-<version>."""
        _tests(session, version)


@nox.session(venv_backend="none", default=False)
def wheels(session: nox.Session) -> None:
    """Every pin of requirements.lock installs from a wheel on each supported Python."""
    for version in PYTHONS:
        try:
            python = interpreter(version)
        except RuntimeError as exc:
            session.error(str(exc))
        session.run(
            python,
            "-m",
            "pip",
            "install",
            "--quiet",
            "--dry-run",
            "--ignore-installed",
            "--no-deps",
            "--only-binary=:all:",
            *(f"--no-binary={name}" for name in SOURCE_ONLY),
            "-r",
            "requirements.lock",
            external=True,
        )
