"""Hashed and signed manifest of an evidence bundle, and its verification (SR-EVD-1).

``manifest.json`` lists the SHA-256 and size of every other file of the bundle, with the
provenance (git commit and dirtiness, configuration hash, Python and package versions,
platform). ``manifest.sig`` is an Ed25519 signature over the exact bytes of ``manifest.json``.
The signing key is kept outside the bundle: a key file given on the command line, or one
generated on first use at ``$SAFECASE_SIGNING_KEY`` or ``~/.config/safecase/signing-key.pem``.
The public key travels in the manifest; pass a trusted public key to :func:`verify_bundle` to
also check *who* signed (the embedded one only proves the bundle is unchanged since signing).
"""

from __future__ import annotations

import base64
import hashlib
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cryptography.exceptions import InvalidSignature
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey, Ed25519PublicKey

from safety.audit.keys import public_key_fingerprint, raw_public_key

MANIFEST = "manifest.json"
SIGNATURE = "manifest.sig"
MANIFEST_SCHEMA = "safecase-manifest/1"

__all__ = [
    "MANIFEST",
    "SIGNATURE",
    "VerifyResult",
    "sha256_file",
    "verify_bundle",
    "write_manifest",
]


def sha256_file(path: Path) -> str:
    """Hex SHA-256 of a file's bytes, streamed."""
    digest = hashlib.sha256()
    with path.open("rb") as handle:
        for block in iter(lambda: handle.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def _bundle_files(bundle: Path) -> list[Path]:
    return sorted(
        p
        for p in bundle.rglob("*")
        if p.is_file() and p.relative_to(bundle).as_posix() not in (MANIFEST, SIGNATURE)
    )


def write_manifest(bundle: Path, provenance: dict[str, Any], key: Ed25519PrivateKey) -> Path:
    """Hash every file in ``bundle``, write ``manifest.json`` and sign it into ``manifest.sig``."""
    files = [
        {
            "path": p.relative_to(bundle).as_posix(),
            "sha256": sha256_file(p),
            "bytes": p.stat().st_size,
        }
        for p in _bundle_files(bundle)
    ]
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
    (bundle / MANIFEST).write_bytes(data)
    (bundle / SIGNATURE).write_bytes(base64.b64encode(key.sign(data)) + b"\n")
    return bundle / MANIFEST


@dataclass(slots=True)
class VerifyResult:
    """The outcome of :func:`verify_bundle`: ``problems`` is empty when all is well."""

    problems: list[str] = field(default_factory=list)
    checked_files: int = 0
    fingerprint: str = ""
    trusted_key: bool = False

    @property
    def ok(self) -> bool:
        """True when no file changed, none was added or removed and the signature holds."""
        return not self.problems


def verify_bundle(bundle: Path, trusted: Ed25519PublicKey | None = None) -> VerifyResult:
    """Check every hash and the signature; name each changed, added or removed file."""
    result = VerifyResult()
    manifest_path = bundle / MANIFEST
    if not bundle.is_dir():
        result.problems.append(f"{bundle}: not a directory")
        return result
    if not manifest_path.is_file():
        result.problems.append(f"removed: {MANIFEST} (the bundle has no manifest)")
        return result
    data = manifest_path.read_bytes()
    try:
        manifest = json.loads(data)
        listed = {entry["path"]: entry["sha256"] for entry in manifest["files"]}
        public_raw = base64.b64decode(manifest["signature"]["public_key"])
        public = Ed25519PublicKey.from_public_bytes(public_raw)
    except (ValueError, KeyError, TypeError) as exc:
        result.problems.append(f"changed: {MANIFEST} (unreadable: {exc})")
        return result
    result.fingerprint = public_key_fingerprint(public)
    signature_path = bundle / SIGNATURE
    if not signature_path.is_file():
        result.problems.append(f"removed: {SIGNATURE}")
    else:
        try:
            public.verify(base64.b64decode(signature_path.read_bytes().strip()), data)
        except (InvalidSignature, ValueError):
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
    present = {p.relative_to(bundle).as_posix(): p for p in _bundle_files(bundle)}
    for path, digest in sorted(listed.items()):
        if path not in present:
            result.problems.append(f"removed: {path}")
        elif sha256_file(present[path]) != digest:
            result.problems.append(f"changed: {path}")
        result.checked_files += 1
    for path in sorted(set(present) - set(listed)):
        result.problems.append(f"added: {path}")
    return result
