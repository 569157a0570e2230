"""The side-by-side section's verdicts on the reference's conclusions, from hand-made figures."""

from __future__ import annotations

from graspstab.report.creep_free import SHORT_WINDOW_POINTS, judge
from graspstab.report.headline import Figure


def _verdicts(test, proxy, sweep):
    return {claim.split(" (")[0]: verdict for claim, verdict, _ in judge(test, proxy, sweep)}


def test_reference_conclusions_hold_on_reference_like_numbers():
    # the reference's own figures (4.3, 4.5, 4.7): every family above the proxy, GRU best,
    # the 0.01 s window within a point of the best
    test = {"cnn": Figure(0.9803, 0.001), "gru": Figure(0.9843, 0.0005),
            "lstm": Figure(0.9841, 0.001)}  # fmt: skip
    sweep = {0.01: {"lstm": Figure(0.98747, 0.0002)}, 0.2: {"gru": Figure(0.990, 0.001)}}
    v = _verdicts(test, Figure(0.9627), sweep)
    assert v == {"Learned models beat the friction-ratio proxy": "holds",
                 "Short windows suffice": "holds", "The GRU ranks best": "holds"}  # fmt: skip


def test_each_conclusion_can_fail_and_undefined_stays_undefined():
    test = {"cnn": Figure(0.90, 0.01), "gru": Figure(0.80, 0.01), "lstm": Figure(0.70, 0.01)}
    gap = (SHORT_WINDOW_POINTS + 0.5) / 100
    sweep = {0.01: {"cnn": Figure(0.80)}, 0.5: {"cnn": Figure(0.80 + gap)}}
    v = _verdicts(test, Figure(0.85), sweep)
    assert v == {"Learned models beat the friction-ratio proxy": "partly",
                 "Short windows suffice": "does not hold", "The GRU ranks best": "does not hold"}
    v = _verdicts(test, Figure(0.95), sweep)
    assert v["Learned models beat the friction-ratio proxy"] == "does not hold"
    undefined = Figure(reason="the test split holds no unstable window")
    v = _verdicts({f: undefined for f in test}, Figure(0.9), {0.01: {"cnn": undefined}})
    assert set(v.values()) == {"undefined"}
