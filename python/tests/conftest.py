"""Shared fixtures: the repository root, the CLI binary and a tiny manifest."""

import os
import pathlib
import shutil

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]

TINY = """
name = "py-tiny"
scene = "cornell"
resolution = [16, 16]

[reference]
integrator = "path"
spp = 16

[base]
integrator = "path"
max_depth = 4

[sweep]
spp = [1, 2]
repeats = 2
"""


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    """The release CLI (`PHOTONLAB_BIN`, else target/release/photonlab). CI sets
    PHOTONLAB_BIN after `cargo test --release` built it: there a missing binary fails."""
    env = os.environ.get("PHOTONLAB_BIN")
    if env:
        p = pathlib.Path(env)
        assert p.is_file(), f"PHOTONLAB_BIN={env}: no such file"
        return p
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    p = target / "release" / "photonlab"
    if not p.is_file():
        found = shutil.which("photonlab")
        if found is None:
            pytest.skip(f"no photonlab CLI at {p} (cargo build --release, or set PHOTONLAB_BIN)")
        p = pathlib.Path(found)
    return p


@pytest.fixture
def tiny_manifest(tmp_path: pathlib.Path) -> pathlib.Path:
    p = tmp_path / "tiny.toml"
    p.write_text(TINY)
    return p
