"""Where training runs and in what precision: ``train.device`` and ``train.mixed_precision``.

``device: auto`` takes CUDA when torch sees a GPU and the CPU otherwise, so the same config runs
on a laptop, in CI (never a GPU) and on a GPU node; ``cpu`` or ``cuda`` force one (``cuda``
without a GPU fails with the fix). ``mixed_precision: auto`` runs autocast on CUDA only, where it
pays; ``true`` forces it (bfloat16 on the CPU, which tests use to bound what it changes) and
``false`` keeps fp32 everywhere. ``native`` runs autocast where the hardware computes in half
precision natively: on CUDA, and on a CPU with bfloat16 instructions (AMX or AVX512-BF16), else
fp32, since a CPU without them emulates bfloat16 more slowly than it runs fp32. bfloat16 needs no
loss scaling; a GPU without bfloat16 gets float16 with a gradient scaler.
"""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass

import torch

DEVICES = ("auto", "cpu", "cuda")
PRECISIONS = ("auto", "native", True, False)


@dataclass(frozen=True)
class Placement:
    """A resolved device and autocast dtype (None: fp32)."""

    device: torch.device
    amp_dtype: torch.dtype | None

    @property
    def mixed_precision(self) -> bool:
        return self.amp_dtype is not None

    def autocast(self) -> contextlib.AbstractContextManager[None]:
        """Autocast for forward passes (a no-op context in fp32)."""
        if self.amp_dtype is None:
            return contextlib.nullcontext()
        return torch.autocast(self.device.type, dtype=self.amp_dtype)

    def scaler(self) -> torch.amp.GradScaler:
        """Loss scaling, needed by float16 only (disabled, a pass-through, otherwise)."""
        return torch.amp.GradScaler(self.device.type, enabled=self.amp_dtype == torch.float16)

    def describe(self) -> dict[str, str | bool]:
        """What the metrics record says about where a model trained."""
        name = str(self.device)
        if self.device.type == "cuda":
            name += f" ({torch.cuda.get_device_name(self.device)})"
        return {"device": name, "mixed_precision": self.mixed_precision,
                "amp_dtype": str(self.amp_dtype).removeprefix("torch.") if self.amp_dtype
                else "float32"}  # fmt: skip


def cpu_has_native_bf16() -> bool:
    """Whether this CPU computes bfloat16 in hardware (oneDNN's check: AVX512-BF16 or AMX)."""
    return bool(torch.ops.mkldnn._is_mkldnn_bf16_supported())


def resolve(device: str = "auto", mixed_precision: str | bool = "auto") -> Placement:
    """The placement that ``train.device`` and ``train.mixed_precision`` name on this machine."""
    if device not in DEVICES:
        raise ValueError(f"train.device = {device!r} is not one of {DEVICES}")
    if mixed_precision not in PRECISIONS:
        raise ValueError(
            f"train.mixed_precision = {mixed_precision!r} is not one of auto, native, true, false"
        )
    cuda = torch.cuda.is_available()
    if device == "cuda" and not cuda:
        raise RuntimeError(
            "train.device = cuda but torch sees no GPU (torch.cuda.is_available() is False): "
            "set train.device: auto (or cpu), or install a CUDA build of torch on a GPU machine."
        )
    dev = torch.device("cuda" if device == "cuda" or (device == "auto" and cuda) else "cpu")
    if mixed_precision == "auto":
        amp = dev.type == "cuda"
    elif mixed_precision == "native":
        amp = dev.type == "cuda" or cpu_has_native_bf16()
    else:
        amp = bool(mixed_precision)
    if not amp:
        return Placement(dev, None)
    if dev.type == "cuda" and not torch.cuda.is_bf16_supported():
        return Placement(dev, torch.float16)
    return Placement(dev, torch.bfloat16)


@contextlib.contextmanager
def on_device(module: torch.nn.Module, placement: Placement) -> Iterator[torch.nn.Module]:
    """``module`` moved to the placement's device for the block, and back to the CPU after it
    (checkpoints, evaluation and the monitor export all expect CPU weights)."""
    module.to(placement.device)
    try:
        yield module
    finally:
        module.to("cpu")
