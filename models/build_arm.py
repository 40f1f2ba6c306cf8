"""Build ``models/arm_obstacle.xml`` and ``data/arm_traj.npz``: a Kinova Jaco arm sweeping into an I-beam.

The arm is dm-control's Jaco (links and three-finger hand, meshes from
``dm_control/third_party/kinova``, Apache-2.0, copied to ``models/kinova/``)
with its six hinge joints; the fingers are fixed.  Joints 2 and 3 get an extra
half turn in their body frames so that the poses used here have
``|angle| < pi`` (their MuJoCo ranges centre on pi in the original model).
The obstacle is an I shape of three boxes (two flanges and a web).
Bounding ellipsoids come from :func:`mjccd.mujoco.fit_model` (``tolerance=None``): 10 on the arm (one
per link body, the hand, each finger), 3 on the obstacle (one per box).

The scripted motion: every joint follows ``tan(theta/2)`` linear in time
between two key poses, so the ``chain`` motion of each frame interval (and of
the whole sweep) is exact.  The file stores the key poses (``keyframes``) and
``qpos`` sampled along the path.

    python models/build_arm.py
"""
import pathlib
import tempfile

import mujoco
import numpy as np

from mjccd.mujoco import fit_model

ROOT = pathlib.Path(__file__).resolve().parents[1]
HALF_TURN_Z = "0 0 0 1"  # appended to the body quaternions of b_2 and b_3

ARM = """<mujoco model="arm_obstacle">
  <compiler angle="radian" meshdir="kinova/"/>
  <option timestep="0.01"/>
  <visual><global offwidth="960" offheight="720"/></visual>
  <asset>
    <material name="dark_gray" rgba="0.15 0.15 0.15 1"/>
    <material name="light_gray" rgba="0.7 0.7 0.7 1"/>
    <mesh name="base" file="base.stl"/>
    <mesh name="shoulder" file="shoulder.stl"/>
    <mesh name="arm" file="arm.stl"/>
    <mesh name="forearm" file="forearm.stl"/>
    <mesh name="wrist" file="wrist.stl"/>
    <mesh name="hand_3finger_main" file="hand_3finger_main.stl"/>
    <mesh name="hand_3finger_insert" file="hand_3finger_insert.stl"/>
    <mesh name="finger_proximal" file="finger_proximal.stl"/>
    <mesh name="finger_distal" file="finger_distal.stl"/>
  </asset>
  <default>
    <geom type="mesh" material="dark_gray" contype="0" conaffinity="0"/>
    <joint type="hinge" damping="0.01"/>
    <default class="large_ring"><geom type="cylinder" material="light_gray" size="0.044 0.011" mass="0"/></default>
    <default class="small_ring"><geom type="cylinder" material="light_gray" size="0.035 0.009" mass="0"/></default>
    <default class="finger"><geom material="light_gray"/></default>
    <default class="beam"><geom type="box" rgba="0.55 0.4 0.25 1"/></default>
  </default>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1" directional="true"/>
    <geom name="floor" type="plane" size="2 2 0.1" rgba="0.85 0.85 0.85 1" contype="0" conaffinity="0"/>
    <body name="b_base">
      <geom name="base" mesh="base" mass="0.718306"/>
      <body name="b_1" pos="0 0 0.15675" quat="0 0 1 0">
        <joint name="joint_1"/>
        <geom name="link_1" mesh="shoulder" mass="0.643205"/>
        <geom name="ring_1" class="large_ring"/>
        <body name="b_2" pos="0 0.0016 -0.11875" quat="QUAT2">
          <joint name="joint_2"/>
          <geom name="link_2" mesh="arm" mass="1.16915"/>
          <geom name="ring_2" class="large_ring"/>
          <body name="b_3" pos="0 -0.41 0" quat="QUAT3">
            <joint name="joint_3"/>
            <geom name="link_3" mesh="forearm" mass="0.673443"/>
            <geom name="ring_3" class="large_ring"/>
            <body name="b_4" pos="0 0.2073 -0.0114" quat="0 0 -0.707107 0.707107">
              <joint name="joint_4"/>
              <geom name="link_4" mesh="wrist" mass="0.221432"/>
              <geom name="ring_4" class="small_ring"/>
              <body name="b_5" pos="0 -0.03703 -0.06414" quat="0 0 0.5 0.866025">
                <joint name="joint_5"/>
                <geom name="link_5" mesh="wrist" mass="0.221432"/>
                <geom name="ring_5" class="small_ring"/>
                <body name="b_6" pos="0 -0.03703 -0.06414" quat="0 0 0.5 0.866025">
                  <joint name="joint_6"/>
                  <body name="hand" quat="0 0.70710678118 0.70710678118 0">
                    <geom name="link_6_main" mesh="hand_3finger_main" mass="0.54719"/>
                    <geom name="link_6_insert" mesh="hand_3finger_insert" material="light_gray" mass="0"/>
                    <body name="b_finger_1" pos="0.00279 0.03126 -0.11467" quat="0.24396 -0.63159 -0.38818 0.62521">
                      <geom name="finger_knuckle_1" class="finger" mesh="finger_proximal" mass="0.0255"/>
                      <geom name="finger_tip_1" class="finger" mesh="finger_distal" pos="0.044 -0.003 0" mass="0.0133"/>
                    </body>
                    <body name="b_finger_2" pos="-0.02226 -0.02707 -0.11482" quat="0.601679 -0.254671 0.659653 -0.37146">
                      <geom name="finger_knuckle_2" class="finger" mesh="finger_proximal" mass="0.0255"/>
                      <geom name="finger_tip_2" class="finger" mesh="finger_distal" pos="0.044 -0.003 0" mass="0.0133"/>
                    </body>
                    <body name="b_finger_3" pos="0.02226 -0.02707 -0.11482" quat="0.659653 -0.37146 0.601679 -0.254671">
                      <geom name="finger_knuckle_3" class="finger" mesh="finger_proximal" mass="0.0255"/>
                      <geom name="finger_tip_3" class="finger" mesh="finger_distal" pos="0.044 -0.003 0" mass="0.0133"/>
                    </body>
                  </body>
                </body>
              </body>
            </body>
          </body>
        </body>
      </body>
    </body>
    <body name="obstacle" pos="OBSTACLE_POS">
      <geom name="flange_top" class="beam" pos="0 0 0.27" size="0.05 0.16 0.025"/>
      <geom name="web" class="beam" pos="0 0 0" size="0.03 0.04 0.245"/>
      <geom name="flange_bottom" class="beam" pos="0 0 -0.27" size="0.05 0.16 0.025"/>
    </body>
  </worldbody>
</mujoco>
"""

# key poses (radians; joints 2 and 3 relative to their half-turned frames)
KEY0 = np.array([-1.0, -0.85, 1.15, 0.4, -0.5, 0.3])
KEY1 = np.array([1.0, -0.75, 1.05, -0.4, 0.5, -0.3])
FRAMES = 121
OBSTACLE_POS = (0.55, 0.0, 0.45)


def _quat_mul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return [aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
            aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw]


def source_xml():
    q2 = _quat_mul([0, 0, -0.707107, 0.707107], [0, 0, 0, 1])
    q3 = _quat_mul([0, 0, 1, 0], [0, 0, 0, 1])
    return (ARM.replace("QUAT2", " ".join(f"{x:.7g}" for x in q2))
               .replace("QUAT3", " ".join(f"{x:.7g}" for x in q3))
               .replace("OBSTACLE_POS", " ".join(f"{x:g}" for x in OBSTACLE_POS)))


def tan_half_path(key0, key1, t):
    """Joint angles (len(t), 6) with tan(theta/2) linear in t from key0 to key1."""
    a, b = np.tan(key0 / 2), np.tan(key1 / 2)
    return 2.0 * np.arctan((1.0 - t)[:, None] * a + t[:, None] * b)


def build(model_path, traj_path):
    with tempfile.NamedTemporaryFile("w", suffix=".xml", dir=model_path.parent, delete=False) as fh:
        fh.write(source_xml())
        src = pathlib.Path(fh.name)
    try:
        model = mujoco.MjModel.from_xml_path(str(src))
        arm = ["b_base", "b_1", "b_2", "b_3", "b_4", "b_5", "hand", "b_finger_1", "b_finger_2", "b_finger_3"]
        bodies = fit_model(model, tolerance=None, per="body", bodies=arm, include_visual=True)
        beams = fit_model(model, tolerance=None, per="geom", bodies=["obstacle"], include_visual=True)
        lines = []
        for s in (bodies, beams):
            for k, name in enumerate(s.bodies):
                label = s.geoms[k] if s.geoms[k] else name
                lines.append((name, f'<geom name="{label}_bound" type="ellipsoid" size="{_f(s.radii[k])}" '
                                    f'pos="{_f(s.positions[k])}" quat="{_f(s.quaternions[k])}" contype="0" '
                                    f'conaffinity="0" group="5" mass="0" rgba="0.3 0.5 0.9 0.35"/>'))
    finally:
        src.unlink()
    text = source_xml()
    for body, line in lines:
        marker = f'<body name="{body}"'
        at = text.index(marker)
        end = text.index(">", at) + 1
        indent = " " * (text.rfind("\n", 0, at) and at - text.rfind("\n", 0, at) - 1) + "  "
        text = text[:end] + "\n" + indent + line + text[end:]
    model_path.write_text(text)
    t = np.linspace(0.0, 1.0, FRAMES)
    np.savez(traj_path, qpos=tan_half_path(KEY0, KEY1, t), time=2.0 * t, keyframes=np.stack([KEY0, KEY1]))


def _f(v):
    return " ".join(f"{x:.9g}" for x in v)


def main():
    model_path = ROOT / "models" / "arm_obstacle.xml"
    traj_path = ROOT / "data" / "arm_traj.npz"
    build(model_path, traj_path)
    print(f"{model_path}, {traj_path}: {FRAMES} frames")


if __name__ == "__main__":
    main()
