"""The analytic two-finger scene the replay and closed-loop tests share: a free box between two
position-servoed slide fingertips, so statics (kp times the target offset) and Coulomb friction
give the expected forces by hand."""

from __future__ import annotations


def two_finger_box(
    mass: float,
    half: float,
    force_limit: float,
    *,
    kp: float = 1000.0,
    mu: float = 1.0,
    dt: float = 0.0005,
    palm: bool = True,
) -> str:
    """The MJCF of the scene: fingertips on slides along x at +-35 mm, the box at the origin,
    no gravity (tests apply their own loads); ``palm`` adds a fixed palm body away from the box."""
    friction = f'friction="{mu} 0.005 0.0001"'
    tip = f'<geom type="box" size="0.01 0.015 0.015" mass="0.05" {friction}/>'
    palm_body = (
        '\n      <body name="palm" pos="0 0.1 0.05"><geom type="box" size="0.01 0.01 0.01"/></body>'
        if palm
        else ""
    )
    return f"""
<mujoco>
  <option timestep="{dt}" cone="elliptic" impratio="10" gravity="0 0 0"/>
  <worldbody>
    <body name="hand">
      <body name="tip_a" pos="-0.035 0 0">
        <joint name="slide_a" type="slide" axis="1 0 0" damping="5"/>
        {tip}
      </body>
      <body name="tip_b" pos="0.035 0 0">
        <joint name="slide_b" type="slide" axis="-1 0 0" damping="5"/>
        {tip}
      </body>{palm_body}
    </body>
    <body name="object">
      <freejoint/>
      <geom type="box" size="{half} {half} {half}" mass="{mass}" {friction}/>
    </body>
  </worldbody>
  <actuator>
    <position name="act_a" joint="slide_a" kp="{kp}" forcerange="-{force_limit} {force_limit}"/>
    <position name="act_b" joint="slide_b" kp="{kp}" forcerange="-{force_limit} {force_limit}"/>
  </actuator>
</mujoco>
"""
