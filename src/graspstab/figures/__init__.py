"""Chapter 4 figures (thesis figs. 4.1-4.10 and the Optuna histories) and how the learning results
are named and shown; the report side of the learning and evaluation stages.

Two kinds of module, kept apart so that the report can read names without loading matplotlib:
``presentation`` (names, orders, undefined-value rules) and ``artefacts`` (the study artefacts a
reader is given) import no plotting library; the report imports only those. The plotting modules,
one per figure group (``baseline`` 4.1-4.3, ``splits`` 4.4, ``sweep`` 4.5-4.7, ``thresholds``
4.8-4.9, ``proxy`` 4.10, ``tuning``, ``crossval``, ``robustness``; ``common`` what they share,
``entry`` rule ``plot_learning``'s entry point), are imported only by the plot rules. Each
``plot_*`` function writes one PNG atomically and returns its path; a NaN metric is marked
"undefined", never drawn as a zero-height bar, and a panel without data says so.
"""
