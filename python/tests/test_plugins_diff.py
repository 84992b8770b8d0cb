"""photonlab.plugins and photonlab.diff."""

import pathlib
import subprocess

import numpy as np
import pytest

import photonlab

ROOT = pathlib.Path(__file__).resolve().parents[2]


def test_plugins_catalogue():
    cat = photonlab.plugins()
    families = {f["key"]: f for f in cat["families"]}
    assert {"integrator", "sampler", "accel", "rr", "gather"} <= set(families)
    integrators = {p["name"] for p in families["integrator"]["plugins"]}
    assert {"path", "photon", "sppm", "ppm"} <= integrators
    common = {p["name"]: p for p in cat["common"]}
    assert common["spp"]["default"] == "16" and common["spp"]["doc"]
    gathers = {p["name"]: p for p in families["gather"]["plugins"]}
    assert any(p["name"] == "ic_tolerance" for p in gathers["irradiance_cache"]["params"])


def test_plugins_markdown_is_the_cli_output(cli):
    out = subprocess.run([str(cli), "plugins", "--markdown"], check=True, capture_output=True, text=True).stdout
    assert photonlab.plugins_markdown().strip() == out.strip()
    assert out.strip() in (ROOT / "docs" / "plugins.md").read_text()


def test_diff_metrics():
    rng = np.random.default_rng(1)
    ref = rng.uniform(0.1, 1.0, size=(32, 48, 3)).astype(np.float32)
    same = photonlab.diff(ref, ref)
    assert same["rmse"] == 0 and same["relmse"] == 0 and same["mean_ratio"] == 1.0
    img = ref * 1.1
    d = photonlab.diff(img, ref, block=16)
    assert d["blocks_judged"] == 2 * 3
    assert d["mean_ratio"] == pytest.approx(1.1, rel=1e-5)
    assert d["worst_block"]["rel"] == pytest.approx(0.1, rel=1e-4)
    expected_rmse = np.sqrt(np.mean((img.astype(np.float64) - ref) ** 2))
    assert d["rmse"] == pytest.approx(expected_rmse, rel=1e-6)
    rel = np.mean((img.astype(np.float64) - ref) ** 2 / (ref.astype(np.float64) ** 2 + 1e-2))
    assert d["relmse"] == pytest.approx(rel, rel=1e-6)
    # float64 and list input are converted.
    assert photonlab.diff(img.astype(np.float64), ref.tolist())["rmse"] == pytest.approx(d["rmse"], rel=1e-6)


def test_diff_matches_the_cli(cli, tmp_path):
    for name, spp in (("a", 1), ("b", 8)):
        subprocess.run([str(cli), "render", "--quiet", "--spp", str(spp), "--resolution", "32x32", "-o", str(tmp_path / f"{name}.exr")],
                       check=True, capture_output=True)
    out = subprocess.run([str(cli), "diff", str(tmp_path / "a.exr"), str(tmp_path / "b.exr"), "--block", "16"],
                         check=True, capture_output=True, text=True).stdout
    d = photonlab.diff(tmp_path / "a.exr", tmp_path / "b.exr", block=16)
    assert f"rmse {d['rmse']:.6f} relmse {d['relmse']:.6f}" in out
    assert f"image mean ratio {d['mean_ratio']:.4f}; {d['blocks_judged']} blocks of 16 px judged" in out


def test_diff_errors():
    a = np.zeros((8, 8, 3), np.float32)
    with pytest.raises(ValueError, match="reference is 4x4"):
        photonlab.diff(a, np.zeros((4, 4, 3)))
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        photonlab.diff(np.zeros((8, 8)), np.zeros((8, 8)))
    with pytest.raises(ValueError, match="block size"):
        photonlab.diff(a, a, block=0)
