"""Key files and the small-file reader under them, each refusal in its own words
(SR-AUD-1, SR-EVD-1).

A key names who signed a log or a bundle; a wrong key must never load quietly, and a key file
that is a FIFO, a device or a loop of links must be an error naming the path, not a hang.
"""

from __future__ import annotations

import base64
import hashlib
import os
import socket
import stat
from pathlib import Path

import pytest
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ec import SECP256R1, generate_private_key
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey

from safety.audit.files import FileReadError, file_kind, open_regular, read_small_file
from safety.audit.keys import (
    MAX_KEY_BYTES,
    SigningKeyError,
    default_key_path,
    load_or_create_key,
    load_private_key,
    load_public_key,
    private_key_pem,
    public_key_fingerprint,
    raw_public_key,
)

CODE = ["safety/audit/keys.py"]
FILES = ["safety/audit/files.py"]


def _public_pem(key: Ed25519PrivateKey) -> bytes:
    return key.public_key().public_bytes(
        serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo
    )


def _ec_private_pem() -> bytes:
    return generate_private_key(SECP256R1()).private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_trusted_key_reads_from_each_of_its_three_spellings(tmp_path: Path) -> None:
    key = Ed25519PrivateKey.generate()
    raw = raw_public_key(key.public_key())
    assert len(raw) == 32
    spellings = {
        "private.pem": private_key_pem(key),
        "public.pem": _public_pem(key),
        "raw.b64": b"  " + base64.b64encode(raw) + b"\n",
    }
    for name, data in spellings.items():
        (tmp_path / name).write_bytes(data)
        assert raw_public_key(load_public_key(tmp_path / name)) == raw, name
    assert public_key_fingerprint(key.public_key()) == "sha256:" + hashlib.sha256(raw).hexdigest()


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_trusted_key_that_is_not_an_ed25519_key_is_refused_naming_the_file(
    tmp_path: Path,
) -> None:
    ec = generate_private_key(SECP256R1())
    cases = {
        "ec-private.pem": (_ec_private_pem(), "expected an Ed25519 key"),
        "ec-public.pem": (
            ec.public_key().public_bytes(
                serialization.Encoding.PEM, serialization.PublicFormat.SubjectPublicKeyInfo
            ),
            "expected an Ed25519 key",
        ),
        "short.b64": (base64.b64encode(bytes(31)), "unreadable ("),
        # Characters outside base64 are refused, not skipped.
        "stray.b64": (
            base64.b64encode(bytes(32))[:20] + b"!" + base64.b64encode(bytes(32))[20:],
            "unreadable (",
        ),
        "not-base64.txt": (b"not a key at all", "unreadable ("),
        "bad.pem": (
            b"-----BEGIN PUBLIC KEY-----\nAAAA\n-----END PUBLIC KEY-----\n",
            "unreadable (",
        ),
    }
    for name, (data, reason) in cases.items():
        path = tmp_path / name
        path.write_bytes(data)
        with pytest.raises(SigningKeyError) as caught:
            load_public_key(path)
        assert str(caught.value).startswith(f"public key {path}: {reason}"), str(caught.value)
    with pytest.raises(SigningKeyError, match=rf"^public key {tmp_path}: not a regular file"):
        load_public_key(tmp_path)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_signing_key_must_be_an_ed25519_private_pem(tmp_path: Path) -> None:
    good = tmp_path / "good.pem"
    key = Ed25519PrivateKey.generate()
    good.write_bytes(private_key_pem(key))
    assert load_private_key(good).private_bytes_raw() == key.private_bytes_raw()
    cases = {
        "ec.pem": (_ec_private_pem(), "expected an Ed25519 key"),
        "public.pem": (_public_pem(key), "not a PEM private key ("),
        "big.pem": (b"x" * (MAX_KEY_BYTES + 1), f"{MAX_KEY_BYTES + 1} bytes; at most"),
    }
    for name, (data, reason) in cases.items():
        path = tmp_path / name
        path.write_bytes(data)
        with pytest.raises(SigningKeyError) as caught:
            load_private_key(path)
        assert str(caught.value).startswith(f"signing key {path}: {reason}"), str(caught.value)
    with pytest.raises(SigningKeyError, match=r"^signing key .*missing\.pem: no such file$"):
        load_private_key(tmp_path / "missing.pem")


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_key_is_never_created_where_it_cannot_be_made_private(tmp_path: Path) -> None:
    blocker = tmp_path / "a-file"
    blocker.write_text("")
    with pytest.raises(SigningKeyError, match=r"^signing key .*a-file/key\.pem: cannot create \("):
        load_or_create_key(blocker / "key.pem")
    # A dangling link is something at the path: loaded (and refused), never written through.
    dangling = tmp_path / "dangling.pem"
    dangling.symlink_to(tmp_path / "nowhere.pem")
    with pytest.raises(SigningKeyError, match=r"^signing key .*dangling\.pem: no such file$"):
        load_or_create_key(dangling)
    assert not (tmp_path / "nowhere.pem").exists()


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_folder_that_exists_keeps_its_mode_and_only_new_ones_are_made_private(
    tmp_path: Path,
) -> None:
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o755)
    shared.chmod(0o755)
    _, path, created = load_or_create_key(shared / "new" / "key.pem")
    assert created
    assert stat.S_IMODE(shared.stat().st_mode) == 0o755
    assert stat.S_IMODE((shared / "new").stat().st_mode) == 0o700
    assert stat.S_IMODE(path.stat().st_mode) == 0o600


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_the_default_key_lives_outside_any_bundle(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("SAFECASE_SIGNING_KEY", str(tmp_path / "k.pem"))
    assert default_key_path() == tmp_path / "k.pem"
    monkeypatch.setenv("SAFECASE_SIGNING_KEY", "")
    monkeypatch.setenv("HOME", str(tmp_path))
    assert default_key_path() == tmp_path / ".config" / "safecase" / "signing-key.pem"


# ------------------------------------------------------------------- the small-file reader


@pytest.mark.requirement("SR-EVD-1", kind="example", code=FILES)
def test_every_kind_of_file_is_named(tmp_path: Path) -> None:
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    sock = socket.socket(socket.AF_UNIX)
    sock.bind(str(tmp_path / "sock"))
    link = tmp_path / "link"
    link.symlink_to(tmp_path)
    (tmp_path / "file").write_text("")
    kinds = {
        tmp_path: "a directory",
        fifo: "a FIFO",
        Path("/dev/null"): "a character device",
        tmp_path / "sock": "a socket",
        tmp_path / "file": "a regular file",
    }
    try:
        for path, kind in kinds.items():
            assert file_kind(path.stat().st_mode) == kind, path
        assert file_kind(link.lstat().st_mode) == "a symbolic link"
        assert file_kind(stat.S_IFBLK) == "a block device"
        assert file_kind(0) == "an unknown kind of file"
        for path, kind in kinds.items():
            if kind == "a regular file":
                continue
            with pytest.raises(FileReadError) as caught:
                read_small_file(path, 10)
            assert str(caught.value) == f"{path}: not a regular file ({kind})"
            assert (caught.value.missing, caught.value.io_error) == (False, False)
    finally:
        sock.close()


@pytest.mark.requirement("SR-EVD-1", kind="example", code=FILES)
def test_a_link_is_refused_where_links_are_not_followed(tmp_path: Path) -> None:
    target = tmp_path / "target"
    target.write_bytes(b"12345")
    link = tmp_path / "link"
    link.symlink_to(target)
    assert read_small_file(link, 5) == b"12345"
    with pytest.raises(FileReadError) as caught:
        read_small_file(link, 5, follow_symlinks=False)
    assert str(caught.value) == f"{link}: not a regular file (a symbolic link)"
    folder = os.open(tmp_path, os.O_RDONLY)
    try:
        assert read_small_file("target", 5, dir_fd=folder) == b"12345"
        fd = open_regular("target", dir_fd=folder)
        os.close(fd)
        with pytest.raises(FileReadError, match=r"^gone: no such file$") as missing:
            open_regular("gone", dir_fd=folder)
        assert (missing.value.missing, missing.value.io_error) == (True, False)
    finally:
        os.close(folder)


@pytest.mark.requirement("SR-EVD-1", kind="example", code=FILES)
def test_a_file_is_read_to_exactly_its_limit(tmp_path: Path) -> None:
    path = tmp_path / "f"
    path.write_bytes(b"x" * 10)
    assert read_small_file(path, 10) == b"x" * 10
    with pytest.raises(FileReadError) as caught:
        read_small_file(path, 9)
    assert str(caught.value) == f"{path}: 10 bytes; at most 9 bytes expected"
    assert read_small_file(tmp_path / "f", 1 << 20) == b"x" * 10
    path.write_bytes(b"")
    assert read_small_file(path, 0) == b""


@pytest.mark.requirement("SR-EVD-1", kind="example", code=FILES)
def test_a_loop_of_links_is_an_error_of_the_system_not_of_the_file(tmp_path: Path) -> None:
    loop = tmp_path / "loop"
    loop.symlink_to(loop.name)
    with pytest.raises(FileReadError) as caught:
        read_small_file(loop, 10)
    assert str(caught.value).startswith(f"{loop}: cannot open (")
    assert (caught.value.missing, caught.value.io_error) == (False, True)


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_folder_made_meanwhile_by_someone_else_is_used_and_left_as_it_is(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Between looking and making, another process made the folder: it is theirs."""
    theirs = tmp_path / "theirs"
    theirs.mkdir()
    theirs.chmod(0o755)
    real = os.path.lexists
    monkeypatch.setattr(os.path, "lexists", lambda p: p != theirs and real(p))
    _, path, created = load_or_create_key(theirs / "ours" / "key.pem")
    monkeypatch.undo()
    assert created
    assert path.is_file()
    assert stat.S_IMODE(theirs.stat().st_mode) == 0o755
    assert stat.S_IMODE((theirs / "ours").stat().st_mode) == 0o700


@pytest.mark.requirement("SR-AUD-1", kind="example", code=CODE)
def test_a_key_made_meanwhile_is_never_overwritten_nor_a_link_written_through(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Between looking and creating, someone put a key (or a link) there: creation fails
    naming the path, and what is there stays as it was."""
    existing = tmp_path / "key.pem"
    existing.write_bytes(b"their key")
    link = tmp_path / "link.pem"
    link.symlink_to(tmp_path / "elsewhere.pem")
    monkeypatch.setattr(os.path, "lexists", lambda p: False)
    for path in (existing, link):
        with pytest.raises(SigningKeyError, match=rf"^signing key {path}: cannot create \("):
            load_or_create_key(path)
    monkeypatch.undo()
    assert existing.read_bytes() == b"their key"
    assert not (tmp_path / "elsewhere.pem").exists()
