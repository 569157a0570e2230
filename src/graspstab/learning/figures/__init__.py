"""Chapter 4 figures (thesis figs. 4.1-4.10 and the Optuna histories) from the study artefacts.

Every ``plot_*`` function writes one PNG (matplotlib, Agg, written atomically) and returns its
path. The inputs are the tables written by :mod:`graspstab.learning.studies`,
:mod:`~graspstab.learning.train_model` and :mod:`~graspstab.learning.tune_model`. Metrics may be NaN
(undefined, e.g. validation AUPRC when the validation split holds no unstable window): such a value
is never drawn as a zero-height bar but marked "undefined", and a panel without any data says so.
:func:`plot_learning` writes them all from the artefacts it is given. One module per figure group:
``baseline`` (4.1-4.3), ``splits`` (4.4), ``sweep`` (4.5-4.7), ``thresholds`` (4.8-4.9),
``proxy`` (4.10), ``tuning``; ``common`` holds what they share, ``entry`` the rule's entry point.
Names, orders and undefined-value rules come from :mod:`graspstab.learning.presentation`.
"""

from graspstab.learning.figures.baseline import plot_benchmark, plot_confusion, plot_objects
from graspstab.learning.figures.common import grouped_bars, no_data, placeholder, plt
from graspstab.learning.figures.entry import load_predictions, load_tuning, plot_learning
from graspstab.learning.figures.proxy import plot_proxy
from graspstab.learning.figures.splits import plot_splits
from graspstab.learning.figures.sweep import plot_latency, plot_operating_points, plot_sweep
from graspstab.learning.figures.thresholds import plot_reliability, plot_threshold_transfer
from graspstab.learning.figures.tuning import plot_tuning
from graspstab.learning.presentation import FIGURES, LEARNING_FIGURES

__all__ = [
    "FIGURES",
    "LEARNING_FIGURES",
    "grouped_bars",
    "load_predictions",
    "load_tuning",
    "no_data",
    "placeholder",
    "plot_benchmark",
    "plot_confusion",
    "plot_latency",
    "plot_learning",
    "plot_objects",
    "plot_operating_points",
    "plot_proxy",
    "plot_reliability",
    "plot_splits",
    "plot_sweep",
    "plot_threshold_transfer",
    "plot_tuning",
    "plt",
]
