"""Ed25519 signing keys: the audit log's head anchor and the evidence manifest (SR-AUD-1, SR-EVD-1).

A private key is a PEM (PKCS#8) file. :func:`load_private_key` reads one that must exist;
:func:`load_or_create_key` also creates it on first use (the key file mode 0600, every folder it
creates 0700 whatever the umask), by default at ``$SAFECASE_SIGNING_KEY`` or
``~/.config/safecase/signing-key.pem``: outside any bundle or log. A trusted public key is PEM
(public or private) or base64 of the raw 32 bytes. Every key file is read through
:func:`safety.audit.files.read_small_file`: a regular file of at most :data:`MAX_KEY_BYTES`.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import os
from pathlib import Path

from cryptography.exceptions import UnsupportedAlgorithm
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

from pipeline.errors import SafecaseError
from safety.audit.files import FileReadError, read_small_file

__all__ = [
    "MAX_KEY_BYTES",
    "SigningKeyError",
    "default_key_path",
    "load_or_create_key",
    "load_private_key",
    "load_public_key",
    "private_key_pem",
    "public_key_fingerprint",
    "raw_public_key",
]

# An Ed25519 PEM is 119 bytes (private) or 113 (public); room for comments, nothing more.
MAX_KEY_BYTES = 16 * 1024


class SigningKeyError(SafecaseError, ValueError):
    """A key file that is not an Ed25519 key of the expected kind, or cannot be read."""


def default_key_path() -> Path:
    """Where the signing key lives when none is given: outside any bundle."""
    env = os.environ.get("SAFECASE_SIGNING_KEY")
    if env:
        return Path(env)
    return Path.home() / ".config" / "safecase" / "signing-key.pem"


def _read_key(path: Path, what: str) -> bytes:
    try:
        return read_small_file(path, MAX_KEY_BYTES)
    except FileReadError as exc:
        raise SigningKeyError(f"{what} {exc}") from None


def private_key_pem(key: Ed25519PrivateKey) -> bytes:
    """The PEM (PKCS#8, unencrypted) bytes of ``key``: what a key file holds."""
    return key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )


def load_private_key(path: Path) -> Ed25519PrivateKey:
    """The Ed25519 private key in the PEM file at ``path``; never creates one.

    Raises :class:`SigningKeyError` naming ``path`` when nothing is there, when it is not a
    readable regular file of at most :data:`MAX_KEY_BYTES`, or not an unencrypted Ed25519 PEM.
    """
    data = _read_key(path, "signing key")
    try:
        key = serialization.load_pem_private_key(data, password=None)
    except (ValueError, TypeError, UnsupportedAlgorithm) as exc:
        raise SigningKeyError(f"signing key {path}: not a PEM private key ({exc})") from None
    if not isinstance(key, Ed25519PrivateKey):
        raise SigningKeyError(f"signing key {path}: expected an Ed25519 key")
    return key


def _make_private_folders(folder: Path) -> None:
    """Create ``folder`` and its missing parents, each 0700 (the umask cannot widen that)."""
    missing: list[Path] = []
    current = folder
    while not os.path.lexists(current):
        missing.append(current)
        if current.parent == current:
            break
        current = current.parent
    for path in reversed(missing):
        try:
            os.mkdir(path, 0o700)
        except FileExistsError:
            continue  # made meanwhile by someone else: theirs, not ours to change
        # mkdir's mode is masked by the umask; a narrower umask must not lock the owner out.
        os.chmod(path, 0o700)


def load_or_create_key(path: Path | None = None) -> tuple[Ed25519PrivateKey, Path, bool]:
    """Load the Ed25519 private key at ``path`` (default :func:`default_key_path`); create it
    (mode 0600, missing folders 0700) if nothing is there.

    Returns the key, its path, and whether it was created now. Anything at the path that is
    not a readable Ed25519 PEM file (a directory, a FIFO, a dangling link, another key type)
    raises :class:`SigningKeyError` naming the path.
    """
    key_path = path or default_key_path()
    if os.path.lexists(key_path):
        return load_private_key(key_path), key_path, False
    key = Ed25519PrivateKey.generate()
    try:
        _make_private_folders(key_path.parent)
        fd = os.open(key_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW, 0o600)
    except OSError as exc:
        raise SigningKeyError(f"signing key {key_path}: cannot create ({exc.strerror})") from None
    with os.fdopen(fd, "wb") as handle:
        handle.write(private_key_pem(key))
    return key, key_path, True


def raw_public_key(key: Ed25519PublicKey) -> bytes:
    """The 32 raw bytes of an Ed25519 public key."""
    return key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)


def public_key_fingerprint(key: Ed25519PublicKey) -> str:
    """``sha256:<hex>`` of the raw public key, for people to compare."""
    return "sha256:" + hashlib.sha256(raw_public_key(key)).hexdigest()


def load_public_key(path: Path) -> Ed25519PublicKey:
    """A trusted public key: PEM (public or private) or base64 of the raw 32 bytes.

    Raises :class:`SigningKeyError` naming ``path`` when it is not a readable regular file of at
    most :data:`MAX_KEY_BYTES` holding an Ed25519 key.
    """
    data = _read_key(path, "public key")
    try:
        if b"PRIVATE KEY" in data:
            private = serialization.load_pem_private_key(data, password=None)
            if isinstance(private, Ed25519PrivateKey):
                return private.public_key()
        elif b"PUBLIC KEY" in data:
            public = serialization.load_pem_public_key(data)
            if isinstance(public, Ed25519PublicKey):
                return public
        else:
            raw = base64.b64decode(data.strip(), validate=True)
            return Ed25519PublicKey.from_public_bytes(raw)
    except (ValueError, TypeError, UnsupportedAlgorithm, binascii.Error) as exc:
        raise SigningKeyError(f"public key {path}: unreadable ({exc})") from None
    raise SigningKeyError(f"public key {path}: expected an Ed25519 key")
