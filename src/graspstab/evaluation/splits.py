"""Split-robustness assignments (thesis 4.4): distinct (validation pair, test pair) choices.

With twelve objects there are C(12,2) x C(10,2) = 2,970 assignments when the validation and
test roles are kept distinct. The study samples ``count`` of them with a seed, the fixed split
first, every other object training.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence

import numpy as np


def assignment_key(val: Sequence[str], test: Sequence[str]) -> tuple[tuple[str, ...], ...]:
    """Order-free identity of an assignment (the pairs are sets; the roles are not)."""
    return tuple(sorted(val)), tuple(sorted(test))


def all_assignments(objects: Sequence[str], n_val: int = 2, n_test: int = 2) -> list[tuple]:
    """Every (validation set, test set) pair of disjoint object sets, in a fixed order."""
    objs = sorted(objects)
    out = []
    for val in itertools.combinations(objs, n_val):
        rest = [o for o in objs if o not in val]
        for test in itertools.combinations(rest, n_test):
            out.append((val, test))
    return out


def sample_assignments(splits: Mapping[str, str], count: int, seed: int) -> list[dict[str, str]]:
    """``count`` distinct assignments (object -> split) sampled with ``seed``; the first is the
    configured split ``splits`` itself. Fewer are returned only when fewer exist."""
    objects = list(splits)
    fixed_val = [o for o in objects if splits[o] == "val"]
    fixed_test = [o for o in objects if splits[o] == "test"]
    if not fixed_val or not fixed_test:
        raise ValueError("the configured split needs at least one val and one test object")
    pool = all_assignments(objects, len(fixed_val), len(fixed_test))
    fixed = assignment_key(fixed_val, fixed_test)
    others = [p for p in pool if assignment_key(*p) != fixed]
    rng = np.random.default_rng(seed)
    picks = rng.choice(len(others), size=min(count - 1, len(others)), replace=False)
    chosen = [(fixed_val, fixed_test)] + [others[i] for i in sorted(picks)]
    return [
        {o: ("val" if o in val else "test" if o in test else "train") for o in objects}
        for val, test in chosen
    ]
