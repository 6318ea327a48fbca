"""Evidence bundles against a hostile bundle: bounded reads of keys and manifests, no symbolic
link ever followed, no path outside the bundle ever opened, added folders, links and loops
reported, duplicate entries refused, an untrusted signer said so on screen, and the signing
key never shipped inside the bundle it signs (SR-EVD-1)."""

from __future__ import annotations

import base64
import builtins
import io
import json
import os
import stat
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from evidence.manifest import MANIFEST, SIGNATURE, verify_bundle, write_manifest
from pipeline.errors import SafecaseError
from properties.cli_runner import run_safecase
from safety.audit.files import FileReadError, read_small_file
from safety.audit.keys import load_or_create_key, public_key_fingerprint

MANIFEST_CODE = ["evidence/manifest.py", "evidence/cli/main.py"]
KEY = Ed25519PrivateKey.from_private_bytes(bytes(range(32)))
OTHER = Ed25519PrivateKey.from_private_bytes(bytes(range(1, 33)))


def _pem(key: Ed25519PrivateKey) -> bytes:
    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


def _bundle(tmp_path: Path, key: Ed25519PrivateKey = KEY) -> Path:
    bundle = tmp_path / "bundle"
    (bundle / "plots").mkdir(parents=True)
    (bundle / "evidence.json").write_text('{"a": 1}\n')
    (bundle / "report.html").write_text("<html></html>\n")
    (bundle / "plots" / "p.png").write_bytes(b"\x89PNG fake")
    write_manifest(bundle, {"config_hash": "x"}, key)
    return bundle


def _resign(bundle: Path, change: Callable[[dict[str, Any]], None], key: Ed25519PrivateKey) -> None:
    """Change the manifest and sign it again with ``key``: a consistent, signed bundle."""
    manifest = json.loads((bundle / MANIFEST).read_bytes())
    change(manifest)
    data = (json.dumps(manifest, indent=2, sort_keys=True) + "\n").encode()
    (bundle / MANIFEST).write_bytes(data)
    (bundle / SIGNATURE).write_bytes(base64.b64encode(key.sign(data)) + b"\n")


@pytest.fixture
def opened(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The real path of every file this process opens (after links are resolved)."""
    seen: list[str] = []
    os_open, io_open = os.open, io.open

    def record_fd(fd: int) -> None:
        seen.append(os.readlink(f"/proc/self/fd/{fd}"))

    def spy_os_open(*args: Any, **kwargs: Any) -> int:
        fd = os_open(*args, **kwargs)
        record_fd(fd)
        return fd

    def spy_io_open(*args: Any, **kwargs: Any) -> Any:
        handle = io_open(*args, **kwargs)
        if hasattr(handle, "fileno"):
            record_fd(handle.fileno())
        return handle

    monkeypatch.setattr(os, "open", spy_os_open)
    monkeypatch.setattr(io, "open", spy_io_open)
    monkeypatch.setattr(builtins, "open", spy_io_open)
    return seen


def _inside(paths: list[str], bundle: Path) -> list[str]:
    root = str(bundle.resolve())
    return [p for p in paths if p != root and not p.startswith(root + os.sep)]


# ------------------------------------------------------------------ bounded, regular-only reads


@pytest.mark.requirement("SR-EVD-1", kind="example", code=MANIFEST_CODE)
def test_a_public_key_that_is_not_a_regular_file_is_a_one_line_error(tmp_path: Path) -> None:
    bundle = _bundle(tmp_path)
    fifo = tmp_path / "fifo.pub"
    os.mkfifo(fifo)
    huge = tmp_path / "huge.pub"
    with huge.open("wb") as handle:
        handle.truncate(256 << 20)  # sparse
    cases = {
        Path("/dev/zero"): "not a regular file",
        fifo: "not a regular file",
        tmp_path: "not a regular file",
        huge: "bytes",
        tmp_path / "missing.pub": "no such file",
    }
    for key, why in cases.items():
        # A subprocess with a time limit: /dev/zero and a FIFO would never end.
        done = run_safecase(
            "evidence", "verify", str(bundle), "--public-key", str(key), timeout_s=30
        )
        assert done.returncode == 2, (key, done.stdout, done.stderr)
        assert "Traceback" not in done.stderr
        message = done.stderr.strip()
        assert len(message.splitlines()) == 1, message
        assert str(key) in message
        assert why in message, message


def _nested(bundle: Path) -> None:
    (bundle / MANIFEST).write_bytes(b"[" * 100_000 + b"]" * 100_000)


def _huge_manifest(bundle: Path) -> None:
    with (bundle / MANIFEST).open("r+b") as handle:
        handle.truncate(1 << 30)  # sparse: 1 GiB to whoever reads it


def _fifo_manifest(bundle: Path) -> None:
    (bundle / MANIFEST).unlink()
    os.mkfifo(bundle / MANIFEST)


def _dir_manifest(bundle: Path) -> None:
    (bundle / MANIFEST).unlink()
    (bundle / MANIFEST).mkdir()


def _zero_manifest(bundle: Path) -> None:
    (bundle / MANIFEST).unlink()
    (bundle / MANIFEST).symlink_to("/dev/zero")


def _zero_signature(bundle: Path) -> None:
    (bundle / SIGNATURE).unlink()
    (bundle / SIGNATURE).symlink_to("/dev/zero")


def _huge_int_manifest(bundle: Path) -> None:
    (bundle / MANIFEST).write_bytes(b'{"files": ' + b"9" * 5000 + b"}")


BAD_MANIFESTS: dict[str, tuple[Callable[[Path], None], str]] = {
    "100k nested arrays": (_nested, f"changed: {MANIFEST}"),
    "huge integer": (_huge_int_manifest, f"changed: {MANIFEST}"),
    "1 GiB": (_huge_manifest, "bytes"),
    "fifo": (_fifo_manifest, "not a regular file"),
    "directory": (_dir_manifest, "not a regular file"),
    "link to /dev/zero": (_zero_manifest, "symbolic link"),
    "signature a link to /dev/zero": (_zero_signature, "symbolic link"),
}


@pytest.mark.requirement("SR-EVD-1", kind="example", code=MANIFEST_CODE)
@pytest.mark.parametrize("case", sorted(BAD_MANIFESTS))
def test_a_bad_manifest_fails_with_a_line_not_a_traceback(tmp_path: Path, case: str) -> None:
    bundle = _bundle(tmp_path)
    make, why = BAD_MANIFESTS[case]
    make(bundle)
    done = run_safecase("evidence", "verify", str(bundle), timeout_s=30)
    assert "Traceback" not in done.stderr, done.stderr[-1500:]
    assert done.returncode == 1, (done.stdout, done.stderr[-500:])
    assert why in done.stdout, done.stdout
    assert MANIFEST in done.stdout or SIGNATURE in done.stdout


# ------------------------------------------------------------------ links, folders, duplicates


@pytest.mark.requirement("SR-EVD-1", kind="example", code=MANIFEST_CODE)
def test_a_listed_file_replaced_by_a_link_to_an_identical_copy_fails(
    tmp_path: Path, opened: list[str]
) -> None:
    bundle = _bundle(tmp_path)
    copy = tmp_path / "copy.json"
    copy.write_bytes((bundle / "evidence.json").read_bytes())
    (bundle / "evidence.json").unlink()
    (bundle / "evidence.json").symlink_to(copy)
    opened.clear()
    result = verify_bundle(bundle)
    assert not result.ok
    assert any(p.startswith("link: evidence.json") for p in result.problems), result.problems
    assert _inside(opened, bundle) == [], "opened outside the bundle"


@pytest.mark.requirement("SR-EVD-1", kind="example", code=MANIFEST_CODE)
@pytest.mark.parametrize("target", ["/etc/shadow", "/proc/self/environ", "/dev/zero"])
def test_links_to_system_files_are_reported_and_never_opened(
    tmp_path: Path, opened: list[str], target: str
) -> None:
    bundle = _bundle(tmp_path)
    # Listed under the link's name (re-signed): the bundle claims the target's content.
    (bundle / "secret.txt").symlink_to(target)
    entry = {"path": "secret.txt", "sha256": "0" * 64, "bytes": 0}
    _resign(bundle, lambda m: m["files"].append(entry), KEY)
    opened.clear()
    result = verify_bundle(bundle)
    assert result.problems == [
        f"link: secret.txt -> {target} (a symbolic link; links are never followed)"
    ]
    assert _inside(opened, bundle) == [], "opened outside the bundle"


@pytest.mark.requirement("SR-EVD-1", kind="example", code=MANIFEST_CODE)
def test_added_directories_links_and_loops_are_reported(tmp_path: Path, opened: list[str]) -> None:
    bundle = _bundle(tmp_path)
    (bundle / "empty").mkdir()
    (bundle / "plots" / "loop").symlink_to("..")
    (bundle / "outside").symlink_to(tmp_path)
    (bundle / "dangling").symlink_to(tmp_path / "nowhere")
    opened.clear()
    problems = verify_bundle(bundle).problems
    assert "added: empty/ (a directory)" in problems, problems
    assert "link: plots/loop -> .. (a symbolic link; links are never followed)" in problems
    assert f"link: outside -> {tmp_path} (a symbolic link; links are never followed)" in problems
    assert any(p.startswith("link: dangling -> ") for p in problems), problems
    assert len(problems) == 4, problems
    assert _inside(opened, bundle) == []


@pytest.mark.requirement("SR-EVD-1", kind="example", code=MANIFEST_CODE)
def test_a_fifo_or_device_in_the_bundle_is_reported_not_read(tmp_path: Path) -> None:
    bundle = _bundle(tmp_path)
    os.mkfifo(bundle / "pipe")
    (bundle / "report.html").unlink()
    os.mkfifo(bundle / "report.html")
    problems = verify_bundle(bundle).problems
    assert "not a regular file: pipe (a FIFO)" in problems, problems
    assert "not a regular file: report.html (a FIFO)" in problems, problems


@pytest.mark.requirement("SR-EVD-1", kind="example", code=MANIFEST_CODE)
def test_a_manifest_listing_a_file_twice_or_outside_the_bundle_fails(
    tmp_path: Path, opened: list[str]
) -> None:
    bundle = _bundle(tmp_path)
    _resign(bundle, lambda m: m["files"].append(dict(m["files"][0])), KEY)
    problems = verify_bundle(bundle).problems
    assert problems == [f"{MANIFEST}: lists evidence.json twice"], problems
    outside = tmp_path / "outside.txt"
    outside.write_text("x")
    paths = ("../outside.txt", str(outside), "plots/../evidence.json", "./report.html", "")
    for i, path in enumerate(paths):
        fresh = _bundle(tmp_path / str(i))
        entry = {"path": path, "sha256": "0" * 64, "bytes": 1}
        _resign(fresh, lambda m, e=entry: m["files"].append(e), KEY)  # type: ignore[misc]
        opened.clear()
        problems = verify_bundle(fresh).problems
        assert problems == [f"{MANIFEST}: lists {path!r}, not a plain path inside the bundle"], (
            problems
        )
        assert _inside(opened, fresh) == []


# ------------------------------------------------------------------ who signed


@pytest.mark.requirement("SR-EVD-1", kind="example", code=MANIFEST_CODE)
def test_a_bundle_resigned_by_another_key_says_so_on_screen(tmp_path: Path) -> None:
    bundle = _bundle(tmp_path)
    (bundle / "report.html").write_text("<html>changed</html>\n")
    write_manifest(bundle, {"config_hash": "x"}, OTHER)
    done = run_safecase("evidence", "verify", str(bundle))
    assert done.returncode == 0, done.stdout
    assert done.stdout.startswith("OK: 3 files match the manifest")
    assert public_key_fingerprint(OTHER.public_key()) in done.stdout
    assert "NOT a trusted key" in done.stdout
    trusted = tmp_path / "trusted.pub"
    trusted.write_bytes(base64.b64encode(KEY.public_key().public_bytes_raw()))
    checked = run_safecase("evidence", "verify", str(bundle), "--public-key", str(trusted))
    assert checked.returncode == 1
    assert "not by the trusted key" in checked.stdout


# ------------------------------------------------------------------ the key stays outside


@pytest.mark.requirement("SR-EVD-1", kind="example", code=["evidence/manifest.py"])
@pytest.mark.parametrize("where", ["key.pem", "deep/keys/signing.pem", "junit.xml"])
def test_the_signing_key_is_never_signed_into_the_bundle(tmp_path: Path, where: str) -> None:
    bundle = tmp_path / "bundle"
    bundle.mkdir()
    (bundle / "evidence.json").write_text("{}\n")
    path = bundle / where
    path.parent.mkdir(parents=True, exist_ok=True)
    pem = _pem(KEY)
    # As a key file, or pasted into another file (a log that printed it).
    path.write_bytes(pem if where.endswith(".pem") else b"<log>\n" + pem + b"</log>\n")
    with pytest.raises(SafecaseError, match=f"signing key.*{where}"):
        write_manifest(bundle, {}, KEY)
    assert not (bundle / MANIFEST).exists()
    # Another key's file is not this key: the bundle is signed.
    path.write_bytes(_pem(OTHER))
    write_manifest(bundle, {}, KEY)
    assert verify_bundle(bundle).ok


@pytest.mark.requirement("SR-EVD-1", kind="example", code=["evidence/manifest.py"])
def test_a_key_path_inside_the_bundle_is_refused_before_it_is_created(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from evidence.manifest import check_key_outside

    bundle = tmp_path / "out"
    bundle.mkdir()
    (tmp_path / "alias").symlink_to(bundle)
    for inside in (bundle / "key.pem", bundle / "a" / "b.pem", tmp_path / "alias" / "k.pem"):
        with pytest.raises(SafecaseError, match="inside the bundle"):
            check_key_outside(bundle, inside)
    check_key_outside(bundle, tmp_path / "key.pem")
    check_key_outside(bundle, tmp_path / "out-key.pem")  # a name prefix is not a folder
    monkeypatch.setenv("SAFECASE_SIGNING_KEY", str(bundle / "default.pem"))
    with pytest.raises(SafecaseError, match=r"default\.pem"):
        check_key_outside(bundle, None)


@pytest.mark.requirement("SR-EVD-1", kind="example", code=["evidence/manifest.py"])
def test_links_and_special_files_are_never_signed(tmp_path: Path) -> None:
    for make in (
        lambda b: (b / "link.json").symlink_to(tmp_path / "x"),
        lambda b: os.mkfifo(b / "fifo"),
        lambda b: (b / "empty").mkdir(),
    ):
        bundle = tmp_path / f"b{len(list(tmp_path.iterdir()))}"
        bundle.mkdir()
        (bundle / "evidence.json").write_text("{}\n")
        make(bundle)
        with pytest.raises(SafecaseError):
            write_manifest(bundle, {}, KEY)
        assert not (bundle / MANIFEST).exists()


@pytest.mark.requirement("SR-EVD-1", kind="example", code=["safety/audit/keys.py"])
@pytest.mark.parametrize("umask", [0o000, 0o022, 0o277])
def test_a_created_key_and_its_folders_are_private_whatever_the_umask(
    tmp_path: Path, umask: int
) -> None:
    target = tmp_path / "config" / "safecase" / "signing-key.pem"
    previous = os.umask(umask)
    try:
        key, path, created = load_or_create_key(target)
    finally:
        os.umask(previous)
    assert created
    assert path == target
    assert stat.S_IMODE(target.stat().st_mode) & 0o077 == 0
    assert stat.S_IMODE(target.parent.stat().st_mode) == 0o700
    assert stat.S_IMODE(target.parent.parent.stat().st_mode) == 0o700
    again, _, created_again = load_or_create_key(target)
    assert not created_again
    assert again.private_bytes_raw() == key.private_bytes_raw()


@pytest.mark.requirement("SR-EVD-1", kind="example", code=["safety/audit/files.py"])
def test_a_small_file_read_stops_at_its_limit_whatever_size_it_reports() -> None:
    # /proc files report a size of 0 whatever they hold.
    environ = Path("/proc/self/environ")
    assert environ.stat().st_size == 0
    with pytest.raises(FileReadError, match="more than 8 bytes"):
        read_small_file(environ, 8)
    assert read_small_file(environ, 1 << 20)
