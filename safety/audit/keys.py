"""Ed25519 signing keys: the audit log's head anchor and the evidence manifest (SR-AUD-1, SR-EVD-1).

A private key is read from a PEM file, or created on first use (mode 0600, its folder 0700) at
``$SAFECASE_SIGNING_KEY`` or ``~/.config/safecase/signing-key.pem``: outside any bundle or log.
A trusted public key is PEM (public or private) or base64 of the raw 32 bytes.
"""

from __future__ import annotations

import base64
import hashlib
import os
from pathlib import Path

from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

from pipeline.errors import SafecaseError

__all__ = [
    "SigningKeyError",
    "default_key_path",
    "load_or_create_key",
    "load_public_key",
    "public_key_fingerprint",
    "raw_public_key",
]


class SigningKeyError(SafecaseError, ValueError):
    """A key file that is not an Ed25519 key of the expected kind, or cannot be read."""


def default_key_path() -> Path:
    """Where the signing key lives when none is given: outside any bundle."""
    env = os.environ.get("SAFECASE_SIGNING_KEY")
    if env:
        return Path(env)
    return Path.home() / ".config" / "safecase" / "signing-key.pem"


def load_or_create_key(path: Path | None = None) -> tuple[Ed25519PrivateKey, Path, bool]:
    """Load the Ed25519 private key at ``path``; create it (mode 0600) if it does not exist.

    Returns the key, its path, and whether it was created now.
    """
    key_path = path or default_key_path()
    if key_path.exists():
        try:
            key = serialization.load_pem_private_key(key_path.read_bytes(), password=None)
        except (ValueError, TypeError) as exc:
            raise SigningKeyError(
                f"signing key {key_path}: not a PEM private key ({exc})"
            ) from None
        if not isinstance(key, Ed25519PrivateKey):
            raise SigningKeyError(f"signing key {key_path}: expected an Ed25519 key")
        return key, key_path, False
    key = Ed25519PrivateKey.generate()
    key_path.parent.mkdir(parents=True, exist_ok=True)
    pem = key.private_bytes(
        serialization.Encoding.PEM,
        serialization.PrivateFormat.PKCS8,
        serialization.NoEncryption(),
    )
    fd = os.open(key_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    with os.fdopen(fd, "wb") as handle:
        handle.write(pem)
    return key, key_path, True


def raw_public_key(key: Ed25519PublicKey) -> bytes:
    return key.public_bytes(serialization.Encoding.Raw, serialization.PublicFormat.Raw)


def public_key_fingerprint(key: Ed25519PublicKey) -> str:
    """``sha256:<hex>`` of the raw public key, for people to compare."""
    return "sha256:" + hashlib.sha256(raw_public_key(key)).hexdigest()


def load_public_key(path: Path) -> Ed25519PublicKey:
    """A trusted public key: PEM (public or private) or base64 of the raw 32 bytes."""
    data = path.read_bytes()
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
            return Ed25519PublicKey.from_public_bytes(base64.b64decode(data.strip()))
    except ValueError as exc:
        raise SigningKeyError(f"public key {path}: unreadable ({exc})") from None
    raise SigningKeyError(f"public key {path}: expected an Ed25519 key")
