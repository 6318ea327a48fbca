"""What machine, tools and source tree produced a piece of evidence (SR-EVD-3)."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from importlib import metadata
from pathlib import Path
from typing import Any

__all__ = ["collect_environment", "git_state"]

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
