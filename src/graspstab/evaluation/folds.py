"""Object-level k-fold cross-validation (our extension; docs/results.md "Generalisation across
objects"): every object is a test object exactly once.

The objects are shuffled with a seed and dealt into ``k`` folds of near-equal size. Fold ``i``
tests its own objects, validates on the objects of the next ``val_folds`` folds (cyclically) and
trains on the rest, so no object is in two roles of one fold and thresholds and normalisation,
computed from a fold's own training and validation objects (graspstab.learning.data), never see
its test objects.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def deal_folds(objects: Sequence[str], k: int, seed: int) -> list[list[str]]:
    """The ``k`` folds: the objects (sorted, then shuffled with ``seed``) dealt round-robin, so
    fold sizes differ by at most one."""
    objs = sorted(set(objects))
    if len(objs) != len(objects):
        raise ValueError("the object list has duplicates")
    if k < 3:
        raise ValueError(f"k = {k}: k-fold needs at least 3 folds (train, validation, test)")
    if k > len(objs):
        raise ValueError(f"k = {k} folds but only {len(objs)} objects; choose k <= {len(objs)}")
    order = np.random.default_rng(seed).permutation(len(objs))
    folds: list[list[str]] = [[] for _ in range(k)]
    for i, j in enumerate(order):
        folds[i % k].append(objs[j])
    return [sorted(f) for f in folds]


def kfold_assignments(
    objects: Sequence[str], k: int, seed: int, val_folds: int = 1
) -> list[dict[str, str]]:
    """One object -> split assignment per fold: fold ``i`` is "test", folds ``i+1 ..
    i+val_folds`` (mod k) "val", every other object "train"."""
    if not 1 <= val_folds <= k - 2:
        raise ValueError(f"val_folds = {val_folds} must be between 1 and k - 2 = {k - 2}")
    folds = deal_folds(objects, k, seed)
    out = []
    for i in range(k):
        val = {o for j in range(1, val_folds + 1) for o in folds[(i + j) % k]}
        test = set(folds[i])
        out.append(
            {o: "test" if o in test else "val" if o in val else "train" for o in sorted(objects)}
        )
    return out
