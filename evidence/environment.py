"""What machine, tools and source tree produced a piece of evidence (SR-EVD-3), and which
project: its name, version, commit and the hashes of the files it lists (SR-EVD-8)."""

from __future__ import annotations

import hashlib
import os
import platform
import subprocess
import sys
from collections.abc import Sequence
from importlib import metadata
from pathlib import Path
from typing import Any

from pipeline.compat import tomllib
from pipeline.errors import EvidenceError

__all__ = ["collect_environment", "git_state", "hash_listed_files", "project_provenance"]

# The tools whose versions an assessor needs first; every installed distribution is listed too.
KEY_PACKAGES = (
    "safecase",
    "numpy",
    "scipy",
    "shapely",
    "python-fcl",
    "filterpy",
    "xgboost-cpu",
    "z3-solver",
    "hypothesis",
    "pytest",
    "pytest-benchmark",
    "pyserial",
    "pydantic",
    "cryptography",
)


def _run_git(root: Path, *args: str) -> str | None:
    try:
        done = subprocess.run(
            ["git", *args], cwd=root, capture_output=True, text=True, timeout=20, check=False
        )
    except (OSError, subprocess.SubprocessError):
        return None
    return done.stdout if done.returncode == 0 else None


def git_state(root: Path) -> dict[str, Any]:
    """Commit, branch and dirtiness of the tree at ``root`` ("unknown" outside a repository)."""
    commit = _run_git(root, "rev-parse", "HEAD")
    if commit is None:
        return {"commit": "unknown", "dirty": None, "branch": "unknown", "changed_files": []}
    status = _run_git(root, "status", "--porcelain", "--untracked-files=normal") or ""
    changed = [line[3:] for line in status.splitlines() if line.strip()]
    branch = (_run_git(root, "rev-parse", "--abbrev-ref", "HEAD") or "unknown").strip()
    return {
        "commit": commit.strip(),
        "dirty": bool(changed),
        "branch": branch,
        "changed_files": changed[:200],
    }


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def collect_environment() -> dict[str, Any]:
    """Python, platform, CPU and every installed distribution's version."""
    packages = {}
    for dist in metadata.distributions():
        name = dist.metadata["Name"]
        if name:
            packages[name.lower()] = dist.version
    key = {name: packages.get(name, "not installed") for name in KEY_PACKAGES}
    try:
        import z3

        z3_version = z3.get_version_string()
    except ImportError:  # pragma: no cover - z3 is a hard dependency
        z3_version = "not installed"
    return {
        "python": sys.version.split()[0],
        "python_implementation": platform.python_implementation(),
        "platform": platform.platform(),
        "machine": platform.machine(),
        "cpu": _cpu_model(),
        "cpu_count": os.cpu_count(),
        "z3": z3_version,
        "key_packages": key,
        "packages": dict(sorted(packages.items())),
    }


def _pyproject(root: Path) -> dict[str, Any]:
    """The ``[project]`` table of ``root/pyproject.toml`` ({} when absent or unreadable)."""
    try:
        data = tomllib.loads((root / "pyproject.toml").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError):
        return {}
    project = data.get("project")
    return project if isinstance(project, dict) else {}


def _installed_version(name: str) -> str | None:
    try:
        return metadata.version(name)
    except (metadata.PackageNotFoundError, ValueError):
        return None


def hash_listed_files(root: Path, patterns: Sequence[str]) -> dict[str, str]:
    """SHA-256 of every file that the glob ``patterns`` (relative to ``root``) match, keyed by
    the path relative to ``root``, sorted. A pattern that matches no file, or one that leaves
    ``root``, is an :class:`~pipeline.errors.EvidenceError`: a listed file the bundle does not
    record would be provenance silently missing."""
    hashes: dict[str, str] = {}
    base = root.resolve()
    for pattern in patterns:
        if Path(pattern).is_absolute() or ".." in Path(pattern).parts:
            raise EvidenceError(f"provenance file {pattern!r}: give a path inside {root}")
        files = sorted(p for p in root.glob(pattern) if p.is_file())
        if not files:
            raise EvidenceError(f"provenance file {pattern!r} matches no file under {root}")
        for file in files:
            resolved = file.resolve()
            if not resolved.is_relative_to(base):
                raise EvidenceError(f"provenance file {file}: a link out of {root}")
            rel = resolved.relative_to(base).as_posix()
            hashes[rel] = hashlib.sha256(resolved.read_bytes()).hexdigest()
    return dict(sorted(hashes.items()))


def project_provenance(
    root: Path, *, name: str | None, version: str | None, files: Sequence[str]
) -> dict[str, Any]:
    """The project whose tests produced the evidence (SR-EVD-8).

    ``name`` and ``version`` default to ``[project]`` of ``root/pyproject.toml``; the name then
    to the folder's, the version to that of the installed distribution of that name, else
    ``"unknown"``. ``files`` are hashed by :func:`hash_listed_files`. The tree's commit is
    :func:`git_state` of the same ``root``, which the plugin records beside it.
    """
    table = _pyproject(root)
    project_name = name or str(table.get("name") or root.resolve().name)
    project_version = (
        version or str(table.get("version") or "") or _installed_version(project_name) or "unknown"
    )
    return {
        "name": project_name,
        "version": project_version,
        "root": str(root),
        "files": hash_listed_files(root, files),
    }
