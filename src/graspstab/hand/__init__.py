"""Hand stage: the floating ORCA v2 right hand, capsule/box approximation, contact candidates.

Thesis 3.1.1-3.1.2 and 3.1.4. Entry point: :func:`graspstab.hand.build_hand.build_hand`.
"""
