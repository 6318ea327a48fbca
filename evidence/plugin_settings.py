"""How a project asks for the evidence plugin: command-line and ini options (SR-EVD-7).

The plugin is *active* when a requirements catalogue is named, by the ini option
``safecase_catalogue`` (in ``[tool.pytest.ini_options]`` of pyproject.toml, or pytest.ini) or by
``--safecase-requirements FILE``. Otherwise it is inactive: it registers the ``requirement``
marker, so a ``--strict-markers`` run accepts it, and does nothing else (no ID check, no
bundle); asking for output (``--safecase-out``, ``--safecase-enforce``, ``--safecase-hazards``)
without a catalogue is a one-line usage error.

Ini paths are relative to the folder of the ini file (the rootdir when there is none), as a
project writes them in its own configuration; command-line paths are relative to the working
directory. Docs: docs/plugin.md.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import pytest

from evidence.catalogue import DEFAULT_ID_PATTERN

__all__ = ["PluginSettings", "add_options", "resolve_settings"]

# (name, type, help); the defaults are "" / [] / False.
_INI: tuple[tuple[str, str, str], ...] = (
    (
        "safecase_catalogue",
        "string",
        "requirements catalogue (TOML) of this project; naming one activates the evidence plugin",
    ),
    (
        "safecase_id_pattern",
        "string",
        "regular expression every requirement ID must match whole; a group named 'family' must "
        f"equal the requirement's family (default {DEFAULT_ID_PATTERN})",
    ),
    ("safecase_hazards", "string", "hazard log and assumptions (TOML), optional"),
    ("safecase_project", "string", "project name in the bundle (default: pyproject [project])"),
    (
        "safecase_project_version",
        "string",
        "project version in the bundle (default: pyproject [project], else the installed one)",
    ),
    (
        "safecase_provenance_files",
        "linelist",
        "files (globs relative to the rootdir) whose SHA-256 the bundle records",
    ),
    (
        "safecase_runtime",
        "bool",
        "also record safecase's runtime configuration and classifier model (safecase's own suite)",
    ),
)


@dataclass(frozen=True, slots=True)
class PluginSettings:
    """What an active plugin does in this session.

    ``runtime`` records safecase's own configuration and classifier model in the bundle: set
    by the ini option ``safecase_runtime`` (safecase's suite) or by naming a configuration with
    ``--safecase-config``; another project's bundle carries neither otherwise (SR-EVD-8).
    """

    root: Path
    catalogue: Path
    id_pattern: str
    hazards: Path | None
    project_name: str | None
    project_version: str | None
    provenance_files: tuple[str, ...]
    runtime: bool
    config_path: str | None
    out: Path | None
    enforce: bool
    key: Path | None


def add_options(parser: pytest.Parser) -> None:
    """Register the ``--safecase-*`` options and the ``safecase_*`` ini options."""
    group = parser.getgroup("safecase", "safecase certification evidence")
    group.addoption(
        "--safecase-out",
        metavar="DIR",
        default=None,
        help="write the evidence bundle (evidence.json, report.html, report.md, "
        "junit.xml, signed manifest) into DIR",
    )
    group.addoption(
        "--safecase-config",
        metavar="FILE",
        default=None,
        help="safecase configuration TOML used by the tests (default: built-in defaults); "
        "its hash is recorded in the bundle",
    )
    group.addoption(
        "--safecase-requirements",
        metavar="FILE",
        default=None,
        help="requirements catalogue; overrides the ini option safecase_catalogue and activates "
        "the plugin",
    )
    group.addoption(
        "--safecase-hazards",
        metavar="FILE",
        default=None,
        help="hazard log and assumptions; overrides the ini option safecase_hazards",
    )
    group.addoption(
        "--safecase-key",
        metavar="FILE",
        default=None,
        help="Ed25519 signing key (PEM); created on first use when missing",
    )
    group.addoption(
        "--safecase-enforce",
        action="store_true",
        default=False,
        help="fail the session when a claimed requirement is not SATISFIED",
    )
    for name, kind, text in _INI:
        default: object = False if kind == "bool" else [] if kind == "linelist" else ""
        parser.addini(name, text, type=kind, default=default)  # type: ignore[arg-type]


def _ini_base(config: pytest.Config) -> Path:
    return config.inipath.parent if config.inipath is not None else config.rootpath


def _ini_path(config: pytest.Config, name: str) -> Path | None:
    value = str(config.getini(name) or "").strip()
    return _ini_base(config) / value if value else None


def resolve_settings(config: pytest.Config) -> PluginSettings | None:
    """This session's settings, or None when the plugin is inactive (module docstring).

    Raises :class:`pytest.UsageError` when output is asked for without a catalogue.
    """
    option = config.getoption
    out = option("safecase_out")
    enforce = bool(option("safecase_enforce"))
    hazards_option = option("safecase_hazards")
    catalogue_option = option("safecase_requirements")
    catalogue = (
        Path(catalogue_option) if catalogue_option else _ini_path(config, "safecase_catalogue")
    )
    if catalogue is None:
        asked = [
            flag
            for flag, given in (
                ("--safecase-out", out),
                ("--safecase-enforce", enforce),
                ("--safecase-hazards", hazards_option),
            )
            if given
        ]
        if asked:
            raise pytest.UsageError(
                f"safecase: {asked[0]} needs a requirements catalogue: set safecase_catalogue in "
                "[tool.pytest.ini_options] (or pytest.ini), or pass --safecase-requirements FILE"
            )
        return None
    key = option("safecase_key")
    config_path = option("safecase_config")
    return PluginSettings(
        root=config.rootpath,
        catalogue=catalogue,
        id_pattern=str(config.getini("safecase_id_pattern") or "").strip() or DEFAULT_ID_PATTERN,
        hazards=Path(hazards_option) if hazards_option else _ini_path(config, "safecase_hazards"),
        project_name=str(config.getini("safecase_project") or "").strip() or None,
        project_version=str(config.getini("safecase_project_version") or "").strip() or None,
        provenance_files=tuple(str(f) for f in config.getini("safecase_provenance_files")),
        runtime=bool(config.getini("safecase_runtime")) or config_path is not None,
        config_path=config_path,
        out=Path(out) if out else None,
        enforce=enforce,
        key=Path(key) if key else None,
    )
