"""Window features for the cross-validation's fairness variants (our extension): the proxy's own
signal as an input channel, and a gain-invariant per-window normalisation.

Both act on raw windows (B, W, 5, 2), normal force in channel 0 and shear in channel 1, before the
training split's normalisation (eq. 32), so a model trained with them sees them at test time too.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from graspstab.labels.dataset import NORMAL_CHANNEL, SHEAR_CHANNEL

Transform = Callable[[np.ndarray], np.ndarray]


def ratio_channel(raw: np.ndarray, eps: float) -> np.ndarray:
    """Append |f_t| / max(f_n, eps) per fingertip and timestep as a third channel: the 4.7 proxy's
    ratio, per contact instead of pooled, floored so an unloaded fingertip scores 0."""
    normal, shear = raw[..., NORMAL_CHANNEL], raw[..., SHEAR_CHANNEL]
    ratio = shear / np.maximum(normal, eps)
    return np.concatenate([raw, ratio[..., None].astype(raw.dtype)], axis=-1)


def gain_normalise(raw: np.ndarray, eps: float) -> np.ndarray:
    """Divide each window's forces by its mean total normal force (sum over fingertips, mean over
    timesteps; floored at ``eps``): scaling a sensor's gain leaves the result unchanged."""
    scale = raw[..., NORMAL_CHANNEL].sum(axis=-1).mean(axis=-1)  # (B,)
    return raw / np.maximum(scale, eps)[:, None, None, None].astype(raw.dtype)


def window_transform(features: Mapping[str, Any] | None) -> Transform | None:
    """The transform a variant's ``features`` ask for (keys ratio_channel, window_norm,
    ratio_eps, gain_eps), or None for the plain forces."""
    if not features:
        return None
    gain = features.get("window_norm", "none") == "gain"
    ratio = bool(features.get("ratio_channel", False))
    if not gain and not ratio:
        return None
    ratio_eps, gain_eps = float(features["ratio_eps"]), float(features["gain_eps"])

    def apply(raw: np.ndarray) -> np.ndarray:
        out = np.asarray(raw, dtype=np.float32)
        if gain:
            out = gain_normalise(out, gain_eps)
        if ratio:
            out = ratio_channel(out, ratio_eps)
        return out

    return apply
