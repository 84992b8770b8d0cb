"""photonlab from Python: render, run experiment manifests, compare images.

The same library as the ``photonlab`` command line (the pixels of ``render`` are those
of ``photonlab render``'s EXR for the same parameters; ``run`` writes what ``photonlab
run`` writes). See docs/python.md.

    import photonlab
    img = photonlab.render(builtin="cornell", integrator="sppm", passes=16, resolution=(128, 128))
    cells = photonlab.run("experiments/quick.toml")
    photonlab.diff(img, reference, block=16)["relmse"]
"""

from __future__ import annotations

import io
import json
import os
from typing import Any, Dict, Optional, Sequence, Tuple, Union

import numpy as np

from . import _photonlab

__all__ = ["render", "render_aovs", "run", "plugins", "plugins_markdown", "diff", "read_exr", "builtins", "__version__"]
__version__: str = _photonlab.__version__

PathLike = Union[str, "os.PathLike[str]"]


def _text(key: str, value: Any) -> str:
    """A keyword argument as the command line's text for ``--set KEY=VALUE``."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (tuple, list, np.ndarray)):
        items = [str(int(v)) if isinstance(v, (int, np.integer)) else str(v) for v in value]
        return "x".join(items) if key == "resolution" else ",".join(items)
    if isinstance(value, (float, np.floating)):
        return repr(float(value))
    return str(value)


def _array(image: Tuple[int, int, bytearray]) -> np.ndarray:
    width, height, data = image
    return np.frombuffer(data, dtype=np.float32).reshape(height, width, 3)


def _render(scene, builtin, aovs, progress, params):
    if scene is not None and builtin is not None:
        raise ValueError("give either scene or builtin, not both")
    pairs = [(k, _text(k, v)) for k, v in params.items() if v is not None]
    scene_path = os.fspath(scene) if scene is not None else None
    return _photonlab.render(scene_path, builtin, pairs, list(aovs), bool(progress))


def render(scene: Optional[PathLike] = None, builtin: Optional[str] = None, *, progress: bool = False, **params: Any) -> np.ndarray:
    """Render a scene file or a built-in scene (default ``cornell``).

    ``params`` are the plug-ins' keys (``photonlab.plugins()``), e.g.
    ``integrator="sppm", passes=64, resolution=(128, 128)`` (or ``"128x128"``);
    ``None`` leaves a key at its default. Returns linear RGB radiance as a float32
    array of shape (height, width, 3), row 0 at the top: the pixels of the EXR that
    ``photonlab render`` writes for the same parameters.

    Raises ``ValueError`` for a bad parameter or scene (the CLI's message, naming the
    key or the file and line), ``OSError`` when a file cannot be read. The GIL is
    released while rendering; Ctrl-C stops the render and raises
    ``KeyboardInterrupt``. ``progress=True`` shows the CLI's progress bars on stderr
    (when stderr is a terminal).
    """
    image, _, _ = _render(scene, builtin, (), progress, params)
    return _array(image)


def render_aovs(
    scene: Optional[PathLike] = None,
    builtin: Optional[str] = None,
    aovs: Sequence[str] = ("direct", "caustic", "indirect"),
    *,
    progress: bool = False,
    **params: Any,
) -> Dict[str, Any]:
    """Render the image and extra images (AOVs, ``render --aov``) with one pre-pass.

    Returns a dict: ``"image"`` and each requested AOV name → (H, W, 3) float32
    array, and ``"info"`` → the run's figures (``timings`` in seconds, ``rays``,
    ``threads``, the integrator's counters under ``extra``, the ``config``). The
    ``photon`` integrator's AOVs: direct, caustic, indirect, photons-direct,
    photons-indirect, photons-caustic, cache.
    """
    if isinstance(aovs, str):
        aovs = [a for a in aovs.split(",") if a]
    image, extra, info = _render(scene, builtin, aovs, progress, params)
    out: Dict[str, Any] = {"image": _array(image)}
    for name, img in extra:
        out[name] = _array(img)
    out["info"] = json.loads(info)
    return out


def run(manifest: PathLike, out: Optional[PathLike] = None, force: bool = False, shard: Optional[Union[str, Tuple[int, int]]] = None, *, progress: bool = False):
    """Run an experiment manifest like ``photonlab run`` and return its cells.

    Writes everything the CLI writes under ``out`` (default ``results/NAME``, relative
    to the working directory): images, ``cells.csv``, ``cells.jsonl``, plots,
    ``summary.md``, ``index.html``; finished cells are kept unless ``force``.
    ``shard`` is ``"I/N"`` or ``(I, N)``: only that shard's cells run, and the frame
    holds them without the bias/variance split (``photonlab merge`` adds it).

    Returns a ``pandas.DataFrame`` with the columns of ``cells.csv`` (numbers as
    numbers, empty cells as NaN); ``df.attrs`` holds ``dir``, ``ran``, ``kept`` and
    ``finalized``.
    """
    import pandas as pd

    if isinstance(shard, tuple):
        shard = f"{shard[0]}/{shard[1]}"
    out_path = os.fspath(out) if out is not None else None
    directory, csv, ran, kept, finalized = _photonlab.run(os.fspath(manifest), out_path, bool(force), shard, bool(progress))
    text = {c: str for c in ("cell", "label", "group", "component", "bias_note")}
    df = pd.read_csv(io.StringIO(csv), dtype=text, keep_default_na=False, na_values=[""])
    for c in text:
        if c in df:
            df[c] = df[c].fillna("")
    df.attrs.update({"dir": directory, "ran": ran, "kept": kept, "finalized": finalized})
    return df


def plugins() -> Dict[str, Any]:
    """The catalogue of ``photonlab plugins``: ``common`` keys, ``families`` (each
    with its ``key`` and ``plugins``, each plug-in with its ``params``: name, type,
    default, doc) and the shared parameter ``groups``."""
    return json.loads(_photonlab.plugins())


def plugins_markdown() -> str:
    """``photonlab plugins --markdown`` (docs/plugins.md)."""
    return _photonlab.plugins_markdown()


def _rgb32(a: Any, what: str) -> np.ndarray:
    arr = np.ascontiguousarray(a, dtype=np.float32)
    if arr.ndim != 3 or arr.shape[2] != 3:
        raise ValueError(f"{what}: expected an (H, W, 3) RGB image, got shape {arr.shape}")
    return arr


def diff(img: Any, ref: Any, block: int = 16) -> Dict[str, Any]:
    """Compare an image with a reference like ``photonlab diff --block BLOCK``.

    Both are (H, W, 3) arrays (or EXR paths). Returns the metrics as a dict: ``rmse``,
    ``mse``, ``relmse`` (ε = 0.01, as the experiment runner), ``mae``,
    ``relmse_trimmed``, ``smape``, ``max_pixel_share``, the per-channel means, and the
    block comparison: ``mean_ratio``, ``blocks_judged`` and ``worst_block`` (pixel
    ``x``/``y``, block means ``test``/``reference``, ``rel``, ``std_err``; None when no
    block is judged).
    """
    if isinstance(img, (str, os.PathLike)):
        img = read_exr(img)
    if isinstance(ref, (str, os.PathLike)):
        ref = read_exr(ref)
    a, b = _rgb32(img, "img"), _rgb32(ref, "ref")
    if a.shape != b.shape:
        raise ValueError(f"image is {a.shape[1]}x{a.shape[0]} but the reference is {b.shape[1]}x{b.shape[0]}")
    if int(block) < 1:
        raise ValueError("block size must be at least 1")
    return json.loads(_photonlab.diff(a.shape[1], a.shape[0], a.tobytes(), b.tobytes(), int(block)))


def read_exr(path: PathLike) -> np.ndarray:
    """An EXR written by photonlab as an (H, W, 3) float32 array."""
    return _array(_photonlab.read_exr(os.fspath(path)))


def builtins() -> list:
    """The built-in scene names (``render(builtin=...)``)."""
    return list(_photonlab.builtins())
