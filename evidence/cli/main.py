"""The ``safecase`` entry point: the app, and certify, evidence, config and requirements.

Errors a user can cause (a bad configuration value, an unreadable file) end with one line per
problem and exit code 2, never a traceback (SR-CFG-1; :mod:`evidence.cli.common`).
"""

from __future__ import annotations

import contextlib
import os
import sys
from importlib import metadata
from pathlib import Path
from typing import Annotated, Any, ClassVar

import typer
from rich.table import Table
from rich.text import Text

from evidence.catalogue import load_catalogue
from evidence.cli.common import ConfigOption, err, fail, load_config_or_exit, out, stamp
from evidence.cli.lazy import LazyGroup
from evidence.manifest import check_key_outside, verify_bundle
from pipeline.config import config_hash, to_toml
from pipeline.errors import SafecaseError
from safety.audit.keys import default_key_path, load_or_create_key, load_public_key


class _Commands(LazyGroup):
    """The subcommands with modules of their own, imported when called (evidence.cli.lazy)."""

    lazy: ClassVar[dict[str, tuple[str, str]]] = {
        "sim": ("evidence.cli.sim", "app"),
        "audit": ("evidence.cli.audit", "app"),
        "nav2": ("evidence.cli.nav2", "app"),
        "mcap": ("evidence.cli.mcap", "app"),
        "train": ("evidence.cli.train", "train_command"),
        "run": ("evidence.cli.run", "run_command"),
        "campaign": ("evidence.cli.campaign", "campaign_command"),
    }


app = typer.Typer(
    cls=_Commands,
    name="safecase",
    help="Formal-safety verification and certification harness for AMR obstacle perception.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)
evidence_app = typer.Typer(help="Inspect and verify evidence bundles.", no_args_is_help=True)
config_app = typer.Typer(help="Show and check configurations.", no_args_is_help=True)
app.add_typer(evidence_app, name="evidence")
app.add_typer(config_app, name="config")

PROFILES = ("dev", "ci", "certify", "certify-full")


def _version(value: bool) -> None:
    if value:
        out.print(f"safecase {metadata.version('safecase')}")
        raise typer.Exit(0)


@app.callback()
def _main(
    version: Annotated[
        bool,
        typer.Option("--version", callback=_version, is_eager=True, help="Print the version."),
    ] = False,
) -> None:
    """safecase: an audited runtime and its certification harness."""


def project_root() -> Path:
    """The source tree this safecase runs from (where tests/ and properties/ live)."""
    return Path(__file__).resolve().parents[2]


@app.command()
def certify(
    config: ConfigOption = None,
    out_dir: Annotated[
        Path, typer.Option("--out", help="Parent folder of the certification bundles.")
    ] = Path("out/certification"),
    profile: Annotated[
        str, typer.Option(help=f"Hypothesis profile: {', '.join(PROFILES)}.")
    ] = "certify",
    signing_key: Annotated[
        Path | None,
        typer.Option(
            help="Ed25519 private key (PEM) that signs the bundle; created when missing "
            "(default: $SAFECASE_SIGNING_KEY or ~/.config/safecase/signing-key.pem)."
        ),
    ] = None,
    select: Annotated[
        str | None,
        typer.Option("-k", help="Run a slice: only tests matching this pytest -k expression."),
    ] = None,
    benchmarks: Annotated[
        bool, typer.Option(help="Run the benchmarks (measurement evidence).")
    ] = True,
) -> None:
    """Run the whole suite (properties, proofs, cross-checks, benchmarks) and write a signed
    evidence bundle to OUT/<stamp>/ (and OUT/latest).

    With -k the run is a slice, not a certification: only the requirements its tests touch
    are judged, and the report and the verdict say so.

    Examples: safecase certify; safecase certify --profile ci -k stopping

    Exit codes: 0 CERTIFIED (or, with -k, every requirement the slice touched is SATISFIED);
    1 NOT CERTIFIED (or the slice failed); 2 bad options, configuration or signing key, or a
    -k expression that selects no test.
    """
    from evidence.run import run_certification

    if profile not in PROFILES:
        fail(f"--profile {profile!r}: allowed: {', '.join(PROFILES)}")
    cfg = load_config_or_exit(config)
    _check_signing_key(signing_key, out_dir)
    when = stamp()
    bundle_dir = out_dir / when
    result = run_certification(
        root=project_root(),
        bundle_dir=bundle_dir,
        config_path=config,
        profile=profile,
        key=signing_key,
        select=select,
        benchmarks=benchmarks,
        console=err,
    )
    if result.exit_code == pytest_no_tests_collected():
        fail(f"-k {select!r} selects no test")
    latest = out_dir / "latest"
    with contextlib.suppress(OSError):
        if latest.is_symlink() or latest.exists():
            latest.unlink()
        latest.symlink_to(when, target_is_directory=True)
    out.print(f"config hash {config_hash(cfg)[:16]} ({config or 'built-in defaults'})")
    bundle = result.bundle
    if bundle is not None and bundle.is_slice:
        _print_slice_lines(bundle)
    else:
        _print_family_lines(bundle)
    out.print(f"report: {bundle_dir / 'report.html'}")
    out.print(f"bundle: {bundle_dir} (verify with: safecase evidence verify {bundle_dir})")
    verdict = bundle.summary["certification"] if bundle is not None else "NOT CERTIFIED"
    blocking = bundle.summary["blocking_requirements"] if bundle is not None else []
    if result.exit_code != 0 or verdict in ("NOT CERTIFIED", "SLICE FAIL"):
        why = (
            f"claimed but not satisfied: {', '.join(blocking)}"
            if blocking
            else f"the test session failed (exit {result.exit_code})"
        )
        out.print(f"[bold red]{verdict}:[/] {why}")
        raise typer.Exit(1)
    if verdict == "SLICE PASS":
        n = len(bundle.summary["judged_requirements"]) if bundle is not None else 0
        out.print(
            f"[bold green]SLICE PASS:[/] the {n} requirement(s) this slice touched are SATISFIED "
            "(a slice is not a certification)"
        )
        return
    out.print("[bold green]CERTIFIED:[/] every claimed requirement is SATISFIED")


def pytest_no_tests_collected() -> int:
    """pytest's exit code when no test was selected."""
    import pytest

    return int(pytest.ExitCode.NO_TESTS_COLLECTED)


def _check_signing_key(key: Path | None, out_dir: Path) -> None:
    """Refuse, before any test runs, a key that cannot sign or that would ship in the bundle."""
    path = key if key is not None else default_key_path()
    try:
        check_key_outside(out_dir, key)
        load_or_create_key(key)
    except (SafecaseError, OSError) as exc:
        fail(f"--signing-key {path}: {exc}")


def _print_slice_lines(bundle: Any) -> None:
    """One line per requirement the slice touched, with its verdict."""
    sel = bundle.selection
    out.print(
        f"SLICE {sel['expression']}: {sel['selected']} test(s) run, {sel['deselected']} left "
        "out; requirements the slice touched:",
        highlight=False,
        markup=False,
    )
    judged = set(bundle.summary["judged_requirements"])
    for r in bundle.requirements:
        if r.id in judged:
            out.print(f"  {r.id:12s} {r.status:8s} {r.verdict}", highlight=False, markup=False)


def _print_family_lines(bundle: Any) -> None:
    if bundle is None:
        out.print("[bold red]no evidence was produced[/]")
        return
    for family, counts in bundle.family_verdicts().items():
        title = bundle.families.get(family, family)
        claimed = [r for r in bundle.requirements if r.family == family and r.status == "claimed"]
        if not claimed:
            verdict = "[dim]PLANNED[/]"
        elif any(r.verdict == "VIOLATED" for r in claimed):
            verdict = "[bold red]VIOLATED[/]"
        elif any(r.verdict == "NOT EVIDENCED" for r in claimed):
            verdict = "[bold yellow]NOT EVIDENCED[/]"
        else:
            verdict = "[bold green]SATISFIED[/]"
        detail = ", ".join(f"{n} {v}" for v, n in sorted(counts.items()))
        out.print(f"{family:5s} {title:32s} {verdict}  ({detail})", highlight=False)


@evidence_app.command(
    "verify",
    epilog="Example: safecase evidence verify out/certification/latest --public-key signing.pub"
    "\n\nExit codes: 0 every file matches the manifest and the signature holds (without "
    "--public-key: made by the key the bundle names itself, printed with a NOT-trusted "
    "warning); 1 a file changed, added or removed, a link, FIFO or device in the bundle, a "
    "manifest that lists a file twice or a path outside the bundle, a bad signature, or (with "
    "--public-key) another signer; 2 bad options or a --public-key that cannot be read (missing, "
    "not a regular file, not an Ed25519 key).",
)
def evidence_verify(
    bundle: Annotated[Path, typer.Argument(help="The bundle folder (holding manifest.json).")],
    public_key: Annotated[
        Path | None,
        typer.Option(help="Trusted public key (PEM or base64 raw); checks who signed."),
    ] = None,
) -> None:
    """Check every file hash and the Ed25519 signature of an evidence bundle (SR-EVD-1).

    Nothing in the bundle is followed or read outside it: a symbolic link, a FIFO or device, an
    added directory, a file listed twice or outside the bundle is a failure. Without
    --public-key the signature is checked against the key the bundle carries, which anyone
    who changed the bundle can replace: the signer's fingerprint is printed, marked NOT
    trusted.
    """
    from rich.markup import escape  # bundle paths and problems are not markup

    trusted = None
    if public_key is not None:
        try:
            trusted = load_public_key(public_key)
        except (OSError, SafecaseError) as exc:
            err.print(f"[bold red]error:[/] --public-key: {escape(str(exc))}", highlight=False)
            raise typer.Exit(2) from None
    result = verify_bundle(bundle, trusted)
    if result.ok and result.trusted_key:
        out.print(
            f"OK: {result.checked_files} files match the manifest, signed by the trusted key "
            f"{result.fingerprint}",
            highlight=False,
        )
        return
    if result.ok:
        out.print(
            f"OK: {result.checked_files} files match the manifest and its signature",
            highlight=False,
        )
        out.print(
            f"[bold yellow]WARNING:[/] signed by key {result.fingerprint}, which the bundle "
            "names itself: NOT a trusted key. Whoever changes a bundle can sign it again with "
            "a key of their own; pass --public-key with the signer's public key to check who "
            "signed.",
            highlight=False,
        )
        return
    for problem in result.problems:
        out.print(f"[bold red]FAIL[/] {escape(problem)}", highlight=False)
    raise typer.Exit(1)


@config_app.command("show")
def config_show(config: ConfigOption = None) -> None:
    """Print the effective configuration as TOML, with its hash.

    Example: safecase config show --config mine.toml > effective.toml

    Exit codes: 0 printed; 2 invalid configuration (one line per problem).
    """
    cfg = load_config_or_exit(config)
    out.print(f"# config hash: {config_hash(cfg)}", highlight=False)
    out.print(to_toml(cfg.model_dump(mode="json")), highlight=False, markup=False)


@config_app.command("check")
def config_check(config: Annotated[Path, typer.Argument(help="TOML file to validate.")]) -> None:
    """Validate a configuration file: ranges, types, unknown keys and every rule between
    sections, as `safecase run` and `certify` would load it.

    Example: safecase config check examples/source-warehouse.toml

    Exit codes: 0 valid; 2 invalid (one line per problem naming the key, the value and what
    is allowed).
    """
    cfg = load_config_or_exit(config)
    out.print(f"OK: {config} is valid (config hash {config_hash(cfg)})")


@app.command("requirements")
def requirements_list(
    family: Annotated[str | None, typer.Option(help="Only this family code, e.g. STOP.")] = None,
) -> None:
    """List the safety requirements catalogue (safety/requirements.toml).

    Example: safecase requirements --family STOP

    Exit codes: 0 listed; 2 unknown family.
    """
    catalogue = load_catalogue()
    families = sorted({req.family for req in catalogue.requirements})
    if family is not None and family.upper() not in families:
        fail(f"--family {family!r}: unknown; known: {', '.join(families)}")
    table = Table("ID", "status", "minimum evidence", "claim", show_lines=False)
    for req in catalogue.requirements:
        if family and req.family != family.upper():
            continue
        minimum = ", ".join(f"{k}>={n}" for k, n in req.minimum)
        # Claims hold brackets ("b in [b_min, b_max]"): plain text, never markup.
        table.add_row(Text(req.id), Text(req.status), Text(minimum), Text(req.claim))
    out.print(table)


def main() -> None:
    """Console-script entry point."""
    # Typer reports usage errors with exit code 2 itself; keep matplotlib off any display.
    os.environ.setdefault("MPLBACKEND", "Agg")
    try:
        app()
    except SafecaseError as exc:
        err.print(f"[bold red]error:[/] {exc}")
        sys.exit(2)
