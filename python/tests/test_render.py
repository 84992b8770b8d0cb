"""photonlab.render / render_aovs: the CLI's pixels, parameters as keywords, errors."""

import subprocess

import numpy as np
import pytest

import photonlab


def cli_render(cli, tmp_path, *args):
    out = tmp_path / "cli.exr"
    subprocess.run([str(cli), "render", "--quiet", "-o", str(out), *args], check=True, capture_output=True)
    return photonlab.read_exr(out)


def test_render_shape_dtype_and_determinism():
    a = photonlab.render(builtin="cornell", integrator="path", spp=2, resolution=(24, 16))
    assert a.shape == (16, 24, 3) and a.dtype == np.float32
    assert np.isfinite(a).all() and a.mean() > 0.01
    b = photonlab.render(builtin="cornell", integrator="path", spp=2, resolution="24x16", threads=1)
    np.testing.assert_array_equal(a, b)  # bit-identical for any thread count
    a[0, 0, 0] = 5.0  # writable, owned


@pytest.mark.parametrize(
    "kw, flags",
    [
        (dict(integrator="path", spp=4, resolution=(32, 24)), ["--integrator", "path", "--spp", "4", "--resolution", "32x24"]),
        (
            dict(integrator="sppm", passes=3, resolution=(32, 32), alpha=0.7, sampler="sobol"),
            ["--integrator", "sppm", "--passes", "3", "--resolution", "32x32", "--alpha", "0.7", "--sampler", "sobol"],
        ),
        (
            dict(builtin="cornell-glass", integrator="photon", gather="final_gather", spp=2, photons=5000, resolution=(24, 24)),
            ["--builtin", "cornell-glass", "--integrator", "photon", "--gather", "final_gather", "--spp", "2",
             "--photons", "5000", "--resolution", "24x24"],
        ),
    ],
)
def test_same_pixels_as_the_cli_exr(cli, tmp_path, kw, flags):
    np.testing.assert_array_equal(photonlab.render(**kw), cli_render(cli, tmp_path, *flags))


def test_render_aovs(cli, tmp_path):
    kw = dict(integrator="photon", spp=1, photons=4000, resolution=(16, 16))
    out = photonlab.render_aovs(aovs=["direct", "indirect"], **kw)
    assert set(out) == {"image", "direct", "indirect", "info"}
    for k in ("image", "direct", "indirect"):
        assert out[k].shape == (16, 16, 3)
    np.testing.assert_array_equal(out["image"], photonlab.render(**kw))
    info = out["info"]
    assert info["config"]["integrator"] == "photon" and info["rays"] > 0
    assert info["timings"]["render_s"] >= 0 and info["extra"]["photons_emitted"] > 0
    # The AOV is the CLI's OUT.direct.exr.
    cli_render(cli, tmp_path, "--integrator", "photon", "--spp", "1", "--photons", "4000", "--resolution", "16x16", "--aov", "direct")
    np.testing.assert_array_equal(out["direct"], photonlab.read_exr(tmp_path / "cli.direct.exr"))


def test_scene_file(tmp_path, cli):
    subprocess.run([str(cli), "scene", "export", "cornell", str(tmp_path / "sc")], check=True, capture_output=True)
    img = photonlab.render(scene=tmp_path / "sc" / "cornell.toml", spp=1, resolution=(8, 8))
    assert img.shape == (8, 8, 3)


def test_unknown_key_names_the_key():
    with pytest.raises(ValueError, match="unknown parameter `gather_smaples`"):
        photonlab.render(spp=1, resolution=(8, 8), gather_smaples=4)


def test_bad_values_raise_value_error_with_the_cli_message():
    with pytest.raises(ValueError, match="resolution"):
        photonlab.render(resolution="8by8")
    with pytest.raises(ValueError, match="alpha must lie in"):
        photonlab.render(integrator="sppm", alpha=1.5, resolution=(8, 8))
    with pytest.raises(ValueError, match="no-such-scene"):
        photonlab.render(builtin="no-such-scene")
    with pytest.raises(ValueError, match="either scene or builtin"):
        photonlab.render(scene="a.toml", builtin="cornell")
    with pytest.raises(ValueError, match=r"gather.*irradiance_cache|ic_tolerance"):
        # A key of a plug-in that is not chosen is an error naming its owner.
        photonlab.render(integrator="path", ic_tolerance=0.3, resolution=(8, 8))


def test_bad_scene_file_names_file_and_line(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text('[camera]\neye = [0, 1, 3]\nlook_at = "x"\n')
    with pytest.raises(ValueError, match=r"bad\.toml"):
        photonlab.render(scene=p)


def test_missing_files_raise_os_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="nope.toml: cannot read scene file"):
        photonlab.render(scene=tmp_path / "nope.toml")
    with pytest.raises(OSError):
        photonlab.read_exr(tmp_path / "nope.exr")


def test_builtins_listed():
    assert "cornell" in photonlab.builtins()
