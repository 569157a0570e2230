"""The reflex's sweep: one parameter away from the defaults per variant, labelled, with the
threshold scaled and capped, and a clear error for what cannot be swept."""

from __future__ import annotations

import math

import numpy as np
import pytest

from graspstab.closedloop.policies import Policy
from graspstab.closedloop.reflex import ReflexParams
from graspstab.closedloop.sweep import default_variant, sweep_variants
from graspstab.monitor.constants import MonitorConstants


class Half:
    constants = MonitorConstants(np.zeros((5, 2)), np.ones((5, 2)), 0.5, 4)

    def __call__(self, windows: np.ndarray) -> np.ndarray:
        return np.full(len(windows), 0.5)


REFLEX = ReflexParams(0.2, 4.0, 0.01)
PROXY = Policy("proxy", "monitor", Half(), threshold=0.6)


def test_each_variant_differs_from_the_defaults_in_its_parameter_only() -> None:
    sweep = {"amount": [0.1, 0.3], "delay_s": [0.05], "debounce": [3],
             "threshold_scale": [0.5, 2.0], "arm_s": [1.0]}  # fmt: skip
    variants = sweep_variants([PROXY], sweep, REFLEX, 1, 0.0)
    by = {v.label: v for v in variants}
    assert list(by) == ["proxy@amount=0.1", "proxy@amount=0.3", "proxy@delay_s=0.05",
                        "proxy@debounce=3", "proxy@threshold_scale=0.5",
                        "proxy@threshold_scale=2", "proxy@arm_s=1"]  # fmt: skip
    assert by["proxy@amount=0.1"].reflex == ReflexParams(0.1, 4.0, 0.01)
    assert by["proxy@amount=0.1"].debounce == 1 and by["proxy@amount=0.1"].policy is PROXY
    assert by["proxy@delay_s=0.05"].reflex.delay_s == 0.05
    assert by["proxy@debounce=3"].debounce == 3 and by["proxy@debounce=3"].reflex == REFLEX
    assert by["proxy@threshold_scale=0.5"].policy.threshold == pytest.approx(0.3)
    assert by["proxy@threshold_scale=2"].policy.threshold == 1.0  # capped
    assert by["proxy@arm_s=1"].arm_s == 1.0 and by["proxy@arm_s=1"].parameter == "arm_s"
    d = default_variant(PROXY, REFLEX, 1, 0.0)
    assert d.label == "proxy" and d.parameter == "" and math.isnan(d.value)


def test_unknown_parameters_and_monitorless_threshold_sweeps_are_refused() -> None:
    with pytest.raises(ValueError, match="unknown parameter.*gain; valid: amount"):
        sweep_variants([PROXY], {"gain": [1.0]}, REFLEX, 1, 0.0)
    with pytest.raises(ValueError, match="policy 'always' has no monitor"):
        sweep_variants([Policy("always", "always")], {"threshold_scale": [2.0]}, REFLEX, 1, 0.0)
    always = sweep_variants([Policy("always", "always")], {"amount": [0.1]}, REFLEX, 1, 0.0)
    assert [v.label for v in always] == ["always@amount=0.1"]
