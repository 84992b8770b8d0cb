"""photonlab.run: the cells as a DataFrame with the cells.csv columns, files as the CLI writes them."""

import subprocess

import pandas as pd
import pytest

import photonlab


def test_run_returns_the_cells_csv_typed(tiny_manifest, tmp_path):
    out = tmp_path / "out"
    df = photonlab.run(tiny_manifest, out=out)
    header = (out / "cells.csv").read_text().splitlines()[0].split(",")
    assert list(df.columns) == header
    assert len(df) == 4 and df.attrs["ran"] == 4 and df.attrs["finalized"]
    for col in ("rmse", "relmse", "time_total_s", "rel_variance"):
        assert pd.api.types.is_float_dtype(df[col]), col
    for col in ("index", "repeat", "width", "camera_rays"):
        assert pd.api.types.is_integer_dtype(df[col]), col
    assert df["cell"].map(type).eq(str).all() and (df["rmse"] > 0).all()
    # Never a negative bias² (unresolved ones are empty: NaN).
    assert not (df["bias2"] < 0).any() and not (df["rel_bias2"] < 0).any()
    for f in ("summary.md", "index.html", "cells.jsonl", "plots/error_vs_time.svg"):
        assert (out / f).is_file(), f
    # A second run keeps the finished cells; force renders them again.
    again = photonlab.run(tiny_manifest, out=out)
    assert again.attrs["ran"] == 0 and again.attrs["kept"] == 4
    pd.testing.assert_frame_equal(again.drop(columns=[c for c in df if c.endswith("_s")]),
                                  df.drop(columns=[c for c in df if c.endswith("_s")]))
    assert photonlab.run(tiny_manifest, out=out, force=True).attrs["ran"] == 4


def test_run_matches_the_cli(cli, tiny_manifest, tmp_path):
    py = photonlab.run(tiny_manifest, out=tmp_path / "py")
    subprocess.run([str(cli), "run", "--quiet", str(tiny_manifest), "--out", str(tmp_path / "cli")], check=True, capture_output=True)
    cli_df = pd.read_csv(tmp_path / "cli" / "cells.csv")
    stable = [c for c in py.columns if not c.endswith("_s") and c not in ("rays",)]
    assert list(cli_df.columns) == list(py.columns)
    for c in ("rmse", "relmse", "mae", "variance"):
        assert (py[c].to_numpy() == cli_df[c].to_numpy()).all(), c
    assert py[stable].shape == cli_df[stable].shape


def test_shards(tiny_manifest, tmp_path):
    out = tmp_path / "sharded"
    one = photonlab.run(tiny_manifest, out=out, shard="1/2")
    assert len(one) == 2 and not one.attrs["finalized"] and one["index"].tolist() == [0, 2]
    two = photonlab.run(tiny_manifest, out=out, shard=(2, 2))
    assert two["index"].tolist() == [1, 3]
    assert not (out / "cells.csv").exists()  # `photonlab merge` writes it


def test_run_errors(tiny_manifest, tmp_path):
    with pytest.raises(FileNotFoundError, match="cannot read manifest"):
        photonlab.run(tmp_path / "missing.toml")
    bad = tmp_path / "bad.toml"
    bad.write_text(tiny_manifest.read_text().replace("max_depth = 4", "max_depht = 4"))
    with pytest.raises(ValueError, match=r"bad\.toml.*max_depht"):
        photonlab.run(bad, out=tmp_path / "o")
    with pytest.raises(ValueError, match="shard"):
        photonlab.run(tiny_manifest, out=tmp_path / "o", shard="3/2")
