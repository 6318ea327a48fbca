"""Hashed and signed manifest of an evidence bundle, and its verification (SR-EVD-1).

``manifest.json`` lists the SHA-256 and size of every other file of the bundle, with the
provenance (git commit and dirtiness, configuration hash, Python and package versions,
platform). ``manifest.sig`` is an Ed25519 signature over the exact bytes of ``manifest.json``.

A bundle is a folder of regular files in folders, each folder holding at least one file. The
folder itself may be reached through a link (``out/certification/latest``); nothing inside it
is: :func:`write_manifest` refuses to sign a bundle holding a symbolic link, a FIFO, a device or
an empty folder, and :func:`verify_bundle` reports any of them, never follows a link and never
opens a path outside the bundle (every file is opened relative to its folder's descriptor,
without following links). Reads of the manifest and the signature are bounded
(:data:`MAX_MANIFEST_BYTES`, :data:`MAX_SIGNATURE_BYTES`).

The signing key is kept outside the bundle: a key file given on the command line, or one
generated on first use at ``$SAFECASE_SIGNING_KEY`` or ``~/.config/safecase/signing-key.pem``.
:func:`check_key_outside` refuses a key path inside the bundle before the key is created;
:func:`write_manifest` refuses a bundle any file of which holds the signing key. The public key
travels in the manifest; pass a trusted public key to :func:`verify_bundle` to also check *who*
signed (the embedded one only proves the bundle is unchanged since someone signed it).
"""

from __future__ import annotations

import base64
import binascii
import contextlib
import errno
import hashlib
import json
import os
import re
import stat
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

from pipeline.errors import EvidenceError
from safety.audit.files import FileReadError, file_kind, open_regular, read_small_file
from safety.audit.keys import (
    default_key_path,
    private_key_pem,
    public_key_fingerprint,
    raw_public_key,
)

MANIFEST = "manifest.json"
SIGNATURE = "manifest.sig"
MANIFEST_SCHEMA = "safecase-manifest/1"
# A manifest entry is about 200 bytes: 16 MiB hold some 80 000 files.
MAX_MANIFEST_BYTES = 16 * 1024 * 1024
# base64 of a 64-byte signature and a newline: 89 bytes.
MAX_SIGNATURE_BYTES = 1024

__all__ = [
    "MANIFEST",
    "MAX_MANIFEST_BYTES",
    "MAX_SIGNATURE_BYTES",
    "SIGNATURE",
    "VerifyResult",
    "check_key_outside",
    "sha256_file",
    "verify_bundle",
    "write_manifest",
]

_HEX64 = re.compile(r"[0-9a-f]{64}")
_BLOCK = 1 << 20


def sha256_file(path: Path) -> str:
    """Hex SHA-256 of the bytes of the regular file at ``path`` (a link is refused), streamed."""
    fd = open_regular(path, follow_symlinks=False)
    digest = hashlib.sha256()
    with os.fdopen(fd, "rb") as handle:
        for block in iter(lambda: handle.read(_BLOCK), b""):
            digest.update(block)
    return digest.hexdigest()


def check_key_outside(bundle: Path, key_path: Path | None) -> None:
    """Raise :class:`~pipeline.errors.EvidenceError` when the signing key at ``key_path``
    (None: :func:`safety.audit.keys.default_key_path`) is, or would be created, inside
    ``bundle``: every file of a bundle is shipped with it (SR-EVD-1). Links in either path are
    resolved; the key need not exist yet."""
    key = (key_path or default_key_path()).expanduser()
    resolved_key, resolved_bundle = key.resolve(), bundle.expanduser().resolve()
    if resolved_key == resolved_bundle or resolved_bundle in resolved_key.parents:
        raise EvidenceError(
            f"signing key {key}: inside the bundle {bundle}, every file of which is shipped "
            f"and signed; keep the key outside it (default {default_key_path()})"
        )


@dataclass(frozen=True, slots=True)
class _Found:
    """One entry of a bundle: ``kind`` is file, dir, link, other (FIFO, device, socket) or
    loop; ``detail`` the link's target or the kind of file; ``dir_fd``/``name`` open it."""

    rel: str
    kind: str
    detail: str = ""
    dir_fd: int = -1
    name: str = ""
    size: int = 0


def _walk(dir_fd: int, prefix: str, ancestors: frozenset[tuple[int, int]]) -> Iterator[_Found]:
    """Every entry below the folder open as ``dir_fd``, sorted, without following any link.

    A folder's descriptor stays open while its entries are handled, so a file is opened
    relative to it: swapping a folder for a link meanwhile does not lead outside the bundle.
    """
    with os.scandir(dir_fd) as listing:
        names = sorted(entry.name for entry in listing)
    for name in names:
        rel = prefix + name
        try:
            st = os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
        except FileNotFoundError:
            continue  # removed while we looked: not there
        if stat.S_ISLNK(st.st_mode):
            yield _Found(rel, "link", os.readlink(name, dir_fd=dir_fd))
        elif stat.S_ISDIR(st.st_mode):
            identity = (st.st_dev, st.st_ino)
            if identity in ancestors:  # a bind mount of a folder inside itself
                yield _Found(rel, "loop")
                continue
            yield _Found(rel, "dir")
            try:
                sub = os.open(
                    name, os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW | os.O_CLOEXEC, dir_fd=dir_fd
                )
            except OSError as exc:
                if exc.errno == errno.ELOOP:  # swapped for a link since the stat
                    yield _Found(rel, "link", "?")
                else:
                    yield _Found(rel, "other", f"an unreadable directory: {exc.strerror}")
                continue
            try:
                yield from _walk(sub, rel + "/", ancestors | {identity})
            finally:
                os.close(sub)
        elif stat.S_ISREG(st.st_mode):
            yield _Found(rel, "file", dir_fd=dir_fd, name=name, size=st.st_size)
        else:
            yield _Found(rel, "other", file_kind(st.st_mode))


def _hash(found: _Found, needles: tuple[bytes, ...] = ()) -> tuple[str, int, bool]:
    """SHA-256 (hex) and size [bytes] of a found regular file, and whether any of ``needles``
    occurs in it (searched across block boundaries)."""
    fd = open_regular(found.name, follow_symlinks=False, dir_fd=found.dir_fd)
    digest, size, hit = hashlib.sha256(), 0, False
    keep = max((len(n) for n in needles), default=1) - 1
    tail = b""
    with os.fdopen(fd, "rb") as handle:
        for block in iter(lambda: handle.read(_BLOCK), b""):
            digest.update(block)
            size += len(block)
            if needles and not hit:
                window = tail + block
                hit = any(n in window for n in needles)
                tail = window[-keep:] if keep else b""
    return digest.hexdigest(), size, hit


def _key_needles(key: Ed25519PrivateKey) -> tuple[bytes, ...]:
    """Byte strings any copy of ``key`` holds: its PEM body, its raw bytes, their base64/hex."""
    raw = key.private_bytes_raw()
    pem_body = b"".join(private_key_pem(key).splitlines()[1:-1])
    return (pem_body, base64.b64encode(raw), raw.hex().encode("ascii"), raw)


def _open_bundle(bundle: Path) -> int:
    # The bundle folder itself may be a link (out/certification/latest): the user named it.
    return os.open(bundle, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)


def _describe(found: _Found) -> str:
    if found.kind == "link":
        return f"link: {found.rel} -> {found.detail} (a symbolic link; links are never followed)"
    if found.kind == "loop":
        return f"loop: {found.rel}/ (a directory mounted inside itself; not entered)"
    return f"not a regular file: {found.rel} ({found.detail})"


def _ancestors(paths: Iterator[str] | list[str]) -> set[str]:
    """Every folder that holds one of ``paths`` (relative, ``/``-separated)."""
    folders: set[str] = set()
    for path in paths:
        parts = path.split("/")[:-1]
        folders.update("/".join(parts[: i + 1]) for i in range(len(parts)))
    return folders


def _write_at(dir_fd: int, name: str, data: bytes) -> None:
    """Replace ``name`` in the folder ``dir_fd`` with ``data`` (a link there is replaced, its
    target never written)."""
    tmp = f".{name}.tmp"
    with contextlib.suppress(FileNotFoundError):
        os.unlink(tmp, dir_fd=dir_fd)
    fd = os.open(
        tmp,
        os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC,
        0o644,
        dir_fd=dir_fd,
    )
    with os.fdopen(fd, "wb") as handle:
        handle.write(data)
    os.replace(tmp, name, src_dir_fd=dir_fd, dst_dir_fd=dir_fd)


def write_manifest(bundle: Path, provenance: dict[str, Any], key: Ed25519PrivateKey) -> Path:
    """Hash every file in ``bundle``, write ``manifest.json`` and sign it into ``manifest.sig``.

    Raises :class:`~pipeline.errors.EvidenceError`, naming each offending path and writing
    nothing, when the bundle holds a symbolic link, a FIFO, device or socket, an empty folder,
    or a file holding ``key`` (its PEM, raw bytes, base64 or hex): a signed bundle must verify,
    and must not ship the key that signs it (SR-EVD-1).
    """
    needles = _key_needles(key)
    files: list[dict[str, Any]] = []
    problems: list[str] = []
    folders: list[str] = []
    root = _open_bundle(bundle)
    try:
        for found in _walk(root, "", frozenset()):
            if found.rel in (MANIFEST, SIGNATURE):
                continue
            if found.kind == "dir":
                folders.append(found.rel)
            elif found.kind == "file":
                digest, size, leaked = _hash(found, needles)
                if leaked:
                    problems.append(
                        f"the signing key is inside the bundle, in {found.rel}: it would be "
                        "shipped with the evidence it signs; keep the key outside the bundle"
                    )
                files.append({"path": found.rel, "sha256": digest, "bytes": size})
            else:
                problems.append(_describe(found))
        held = _ancestors([f["path"] for f in files])
        problems += [
            f"empty directory: {f}/ (a bundle holds files)" for f in folders if f not in held
        ]
        if problems:
            raise EvidenceError(f"cannot sign the bundle {bundle}: " + "; ".join(problems))
        public = key.public_key()
        manifest = {
            "schema": MANIFEST_SCHEMA,
            "files": files,
            "provenance": provenance,
            "signature": {
                "algorithm": "Ed25519",
                "public_key": base64.b64encode(raw_public_key(public)).decode("ascii"),
                "fingerprint": public_key_fingerprint(public),
                "signed_file": MANIFEST,
                "signature_file": SIGNATURE,
            },
        }
        data = (json.dumps(manifest, indent=2, sort_keys=True) + "\n").encode("utf-8")
        _write_at(root, MANIFEST, data)
        _write_at(root, SIGNATURE, base64.b64encode(key.sign(data)) + b"\n")
    finally:
        os.close(root)
    return bundle / MANIFEST


@dataclass(slots=True)
class VerifyResult:
    """The outcome of :func:`verify_bundle`: ``problems`` is empty when all is well.

    ``fingerprint`` is the signer's key as the manifest names it; ``trusted_key`` is True only
    when a trusted key was given and it is that key."""

    problems: list[str] = field(default_factory=list)
    checked_files: int = 0
    fingerprint: str = ""
    trusted_key: bool = False

    @property
    def ok(self) -> bool:
        """True when no file changed, none was added or removed and the signature holds."""
        return not self.problems


def _plain(path: str) -> bool:
    """A relative ``/``-separated path of real names: nothing that could leave the bundle."""
    parts = path.split("/")
    return (
        bool(path)
        and "\x00" not in path
        and "\\" not in path
        and all(part not in ("", ".", "..") for part in parts)
        and path not in (MANIFEST, SIGNATURE)
    )


def _listed(manifest: Any, result: VerifyResult) -> tuple[dict[str, tuple[str, int]], bytes]:
    """The manifest's entries (path -> (sha256, bytes)) and the signer's raw public key.

    Raises ValueError when the manifest is not a manifest; entries listing a path twice or a
    path that is not plain are problems, and are not checked further.
    """
    if not isinstance(manifest, dict) or manifest.get("schema") != MANIFEST_SCHEMA:
        raise ValueError(f"not a {MANIFEST_SCHEMA} manifest")
    entries, signature = manifest.get("files"), manifest.get("signature")
    if not isinstance(entries, list) or not isinstance(signature, dict):
        raise ValueError("no list of files or no signature block")
    try:
        public_raw = base64.b64decode(str(signature.get("public_key")), validate=True)
    except (binascii.Error, ValueError):
        public_raw = b""
    if len(public_raw) != 32:
        raise ValueError("the signature block's public key is not 32 bytes of base64")
    listed: dict[str, tuple[str, int]] = {}
    for i, entry in enumerate(entries):
        path = entry.get("path") if isinstance(entry, dict) else None
        digest = entry.get("sha256") if isinstance(entry, dict) else None
        size = entry.get("bytes") if isinstance(entry, dict) else None
        if (
            not isinstance(path, str)
            or not isinstance(digest, str)
            or not _HEX64.fullmatch(digest)
            or not isinstance(size, int)
            or isinstance(size, bool)
            or size < 0
        ):
            result.problems.append(f"{MANIFEST}: entry {i} is not a file entry")
        elif not _plain(path):
            result.problems.append(
                f"{MANIFEST}: lists {path[:200]!r}, not a plain path inside the bundle"
            )
        elif path in listed:
            result.problems.append(f"{MANIFEST}: lists {path} twice")
        else:
            listed[path] = (digest, size)
    return listed, public_raw


def _read_at(root: int, name: str, limit: int, result: VerifyResult) -> bytes | None:
    """``name`` in the bundle's top folder, or None with the problem recorded."""
    try:
        return read_small_file(name, limit, follow_symlinks=False, dir_fd=root)
    except FileReadError as exc:
        if exc.missing:
            result.problems.append(f"removed: {name}")
        else:
            result.problems.append(f"changed: {name} ({exc.reason})")
        return None


def _check_signature(
    root: int,
    data: bytes,
    public_raw: bytes,
    trusted: Ed25519PublicKey | None,
    result: VerifyResult,
) -> None:
    public = Ed25519PublicKey.from_public_bytes(public_raw)
    result.fingerprint = public_key_fingerprint(public)
    encoded = _read_at(root, SIGNATURE, MAX_SIGNATURE_BYTES, result)
    if encoded is not None:
        try:
            public.verify(base64.b64decode(encoded.strip(), validate=True), data)
        except (InvalidSignature, binascii.Error, ValueError):
            result.problems.append(
                f"changed: {SIGNATURE} or {MANIFEST} (the signature does not match the manifest)"
            )
    if trusted is not None:
        if raw_public_key(trusted) == public_raw:
            result.trusted_key = True
        else:
            result.problems.append(
                f"{MANIFEST}: signed by {result.fingerprint}, not by the trusted key "
                f"{public_key_fingerprint(trusted)}"
            )


def verify_bundle(bundle: Path, trusted: Ed25519PublicKey | None = None) -> VerifyResult:
    """Check every hash and the signature; name each changed, added or removed file, and every
    link, special file, added folder, duplicate or outside path (module docstring)."""
    result = VerifyResult()
    try:
        root = _open_bundle(bundle)
    except OSError as exc:
        result.problems.append(f"{bundle}: not a directory ({exc.strerror})")
        return result
    try:
        _verify_open(bundle, root, trusted, result)
    finally:
        os.close(root)
    return result


def _verify_open(
    bundle: Path, root: int, trusted: Ed25519PublicKey | None, result: VerifyResult
) -> None:
    data = _read_at(root, MANIFEST, MAX_MANIFEST_BYTES, result)
    if data is None:
        if result.problems == [f"removed: {MANIFEST}"]:
            result.problems[0] += " (the bundle has no manifest)"
        return
    try:
        listed, public_raw = _listed(json.loads(data), result)
    except (ValueError, RecursionError) as exc:
        why = "nested too deeply" if isinstance(exc, RecursionError) else str(exc)[:120]
        result.problems.append(f"changed: {MANIFEST} (unreadable: {why})")
        return
    _check_signature(root, data, public_raw, trusted, result)
    problems: dict[str, str] = {}  # one per path, reported sorted by path
    folders: list[str] = []
    files: set[str] = set()
    for found in _walk(root, "", frozenset()):
        if found.rel in (MANIFEST, SIGNATURE):
            continue  # read above, without following links
        if found.kind == "dir":
            folders.append(found.rel)
            if found.rel in listed:
                problems[found.rel] = f"changed: {found.rel} (a directory, listed as a file)"
        elif found.kind != "file":
            problems[found.rel] = _describe(found)
        elif found.rel not in listed:
            problems[found.rel] = f"added: {found.rel}"
        else:
            files.add(found.rel)
            digest, size = listed[found.rel]
            if found.size != size or _hash(found)[0] != digest:
                problems[found.rel] = f"changed: {found.rel}"
    for path in listed:
        if path not in files and path not in problems:
            problems[path] = f"removed: {path}"
    held = _ancestors(list(listed))
    for folder in folders:
        if folder not in held and folder not in problems:
            problems[folder] = f"added: {folder}/ (a directory)"
    result.checked_files = len(listed)
    result.problems += [problems[p] for p in sorted(problems)]
