"""Evidence-bundle integrity properties (requirement family SR-EVD-*)."""

from __future__ import annotations

import hashlib
import tempfile
from pathlib import Path

import pytest
from cryptography.hazmat.primitives.asymmetric.ed25519 import Ed25519PrivateKey
from hypothesis import given
from hypothesis import strategies as st

from evidence.manifest import MANIFEST, SIGNATURE, verify_bundle, write_manifest

_names = st.from_regex(r"[a-z]{1,8}(/[a-z]{1,8})?\.(json|html|md|xml|png|smt2)", fullmatch=True)
_bundles = st.dictionaries(_names, st.binary(min_size=1, max_size=256), min_size=1, max_size=6)
# Keys from a hash of a drawn seed: drawn raw, the key's bytes could equal a drawn file's (both
# all zero, say), and the signer rightly refuses a bundle that holds its key.
_key = st.integers(0, 2**64 - 1).map(
    lambda seed: Ed25519PrivateKey.from_private_bytes(
        hashlib.sha256(seed.to_bytes(8, "big")).digest()
    )
)


def _write(root: Path, files: dict[str, bytes]) -> None:
    for name, data in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(data)


@pytest.mark.requirement("SR-EVD-1")
@given(files=_bundles, key=_key, data=st.data())
def test_any_single_change_is_detected_and_named(
    files: dict[str, bytes], key: Ed25519PrivateKey, data: st.DataObject
) -> None:
    # Names like "a" and "a/b.json" cannot coexist as file and folder.
    names = sorted(files)
    if any(other.startswith(n.rsplit(".", 1)[0] + "/") for n in names for other in names):
        files = {n: files[n] for n in names if "/" not in n}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        _write(root, files)
        write_manifest(root, {"config_hash": "0" * 64}, key)
        assert verify_bundle(root).ok
        action = data.draw(st.sampled_from(["flip", "truncate", "remove", "add"]), label="action")
        target = data.draw(st.sampled_from(sorted(files)), label="target")
        path = root / target
        if action == "flip":
            blob = path.read_bytes()
            at = data.draw(st.integers(0, len(blob) - 1), label="at")
            bit = data.draw(st.integers(0, 7), label="bit")
            path.write_bytes(blob[:at] + bytes([blob[at] ^ (1 << bit)]) + blob[at + 1 :])
            expected = [f"changed: {target}"]
        elif action == "truncate":
            path.write_bytes(path.read_bytes()[:-1])
            expected = [f"changed: {target}"]
        elif action == "remove":
            path.unlink()
            expected = [f"removed: {target}"]
        else:
            extra = "zz-extra.txt"
            (root / extra).write_bytes(b"x")
            expected = [f"added: {extra}"]
        assert verify_bundle(root).problems == expected


@pytest.mark.requirement("SR-EVD-1")
@given(files=_bundles, key=_key, other=_key)
def test_a_signature_by_another_key_or_over_other_bytes_fails(
    files: dict[str, bytes], key: Ed25519PrivateKey, other: Ed25519PrivateKey
) -> None:
    files = {n: d for n, d in files.items() if "/" not in n} or {"a.json": b"{}"}
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(tmp)
        _write(root, files)
        write_manifest(root, {}, key)
        manifest = (root / MANIFEST).read_bytes()
        # A signature made by a different key over the same manifest.
        import base64

        forged = base64.b64encode(other.sign(manifest)) + b"\n"
        if other.public_key().public_bytes_raw() == key.public_key().public_bytes_raw():
            assert verify_bundle(root).ok
            return
        (root / SIGNATURE).write_bytes(forged)
        problems = verify_bundle(root).problems
        assert problems
        assert "signature does not match" in problems[0]
        # Re-signed honestly by the other key: consistent, but not the trusted key.
        write_manifest(root, {}, other)
        result = verify_bundle(root, trusted=key.public_key())
        assert not result.ok
        assert "not by the trusted key" in result.problems[0]
