#!/usr/bin/env python3
"""Writes poise_humanoid.urdf next to this script.

The URDF is committed; this script documents where every number comes from (inertias are those of
the primitive collision shapes, so shape and inertia always agree). Re-run after editing:
    python3 deploy/robots/poise_humanoid/generate_urdf.py

Larger variants of the same robot (issue #19 item 4: cost as the robot grows), same legs, feet,
torso, arms and total mass, more joints in the upper body:
    python3 deploy/robots/poise_humanoid/generate_urdf.py --joints 32   # -> ../poise_humanoid_32/
    python3 deploy/robots/poise_humanoid/generate_urdf.py --joints 64   # -> ../poise_humanoid_64/
  32: + neck yaw, 3-DoF wrists (yaw, pitch, roll), one 3-joint finger per hand;
  64: + neck yaw, 3-DoF wrists, five fingers per hand (thumb: spread + 2 flexion; the others:
      spread + 3 flexion).
The 0.3 kg fixed hand of the base robot becomes wrist links + palm + phalanges of 0.3 kg in all,
so the masses of the links above the wrist and the total (50.8 kg) are unchanged. A variant also
gets its robot.yaml (base robot's feet, contact, posture; gains of the new joints from their
inertia, see extra_gains). `--out DIR` writes into DIR instead (the tests' drift check).

Conventions: z up, x forward, y left. Lengths in m, masses in kg, angles in rad.
Standing on straight legs the soles are at z = 0 and the pelvis origin at z = 0.90.
"""
import argparse
import os

# --- dimensions -----------------------------------------------------------------------------
HIP_Y = 0.09  # lateral offset of the hip from the pelvis origin
HIP_YAW_Z = -0.07  # hip yaw joint below the pelvis origin
HIP_ROLL_Z = -0.05  # hip roll/pitch joints below the hip yaw joint
THIGH = 0.35
SHANK = 0.35
ANKLE_HEIGHT = 0.08  # ankle axis above the sole
FOOT_X = (-0.08, 0.14)  # sole extent along x in the foot frame (ankle at x = 0)
FOOT_W = 0.11
FOOT_T = 0.05  # foot box thickness; its bottom face is the sole
TORSO_Z = 0.10
SHOULDER = (0.0, 0.20, 0.34)
UPPER_ARM = 0.26
FOREARM = 0.22

# small joint damping / dry friction (N m s / rad, N m)
DAMPING = 0.05
FRICTION = 0.02


def box_inertia(m, x, y, z):
    return (m * (y * y + z * z) / 12.0, m * (x * x + z * z) / 12.0, m * (x * x + y * y) / 12.0)


def cyl_inertia(m, r, h):  # axis along z
    a = m * (3 * r * r + h * h) / 12.0
    return (a, a, m * r * r / 2.0)


def sphere_inertia(m, r):
    a = 0.4 * m * r * r
    return (a, a, a)


def f(v):
    return " ".join(f"{x:.6g}" for x in v)


out = []


def link(name, mass=None, com=(0, 0, 0), inertia=None, shape=None, shape_xyz=(0, 0, 0), rpy=(0, 0, 0)):
    out.append(f'  <link name="{name}">')
    if mass is not None:
        ixx, iyy, izz = inertia
        out.append("    <inertial>")
        out.append(f'      <origin xyz="{f(com)}" rpy="0 0 0"/>')
        out.append(f'      <mass value="{mass:.6g}"/>')
        out.append(
            f'      <inertia ixx="{ixx:.6g}" ixy="0" ixz="0" iyy="{iyy:.6g}" iyz="0" izz="{izz:.6g}"/>'
        )
        out.append("    </inertial>")
    if shape is not None:
        for tag in ("visual", "collision"):
            out.append(f"    <{tag}>")
            out.append(f'      <origin xyz="{f(shape_xyz)}" rpy="{f(rpy)}"/>')
            out.append(f"      <geometry>{shape}</geometry>")
            out.append(f"    </{tag}>")
    out.append("  </link>")


def joint(name, jtype, parent, child, xyz, axis=None, lower=None, upper=None, effort=None, vel=None,
          dyn=None):
    out.append(f'  <joint name="{name}" type="{jtype}">')
    out.append(f'    <parent link="{parent}"/>')
    out.append(f'    <child link="{child}"/>')
    out.append(f'    <origin xyz="{f(xyz)}" rpy="0 0 0"/>')
    if axis is not None:
        out.append(f'    <axis xyz="{f(axis)}"/>')
        out.append(
            f'    <limit lower="{lower:.6g}" upper="{upper:.6g}" effort="{effort:.6g}" velocity="{vel:.6g}"/>'
        )
        if dyn is None:
            out.append(f'    <dynamics damping="{DAMPING}" friction="{FRICTION}"/>')
        else:  # (damping, friction) of a light joint (variants)
            out.append(f'    <dynamics damping="{dyn[0]:.6g}" friction="{dyn[1]:.6g}"/>')
    out.append("  </joint>")


def box(x, y, z):
    return f'<box size="{f((x, y, z))}"/>'


def cyl(r, h):
    return f'<cylinder radius="{r:.6g}" length="{h:.6g}"/>'


def sphere(r):
    return f'<sphere radius="{r:.6g}"/>'


# --- variants (--joints 32 / 64): neck, wrists, fingers -------------------------------------
DT = 0.001  # control period the gains are made for (1 kHz)
WN = 100.0  # natural frequency [rad/s] of an added joint's PD, critically damped (extra_gains)
PALM = (0.07, 0.025, 0.08)  # palm box (x, y, z); the fingers hang from its lower face
WRIST_LINK_M, WRIST_LINK_R = 0.015, 0.02
KNUCKLE_M, KNUCKLE_R = 0.003, 0.009
HAND_M = 0.3  # the base robot's fixed hand: wrist links + palm + fingers weigh the same
# joint damping / friction of the light joints: explicit in the simulator, so they must stay small
# against the inertia (damping * dt / I < 0.05 for each)
LIGHT_DAMPING_NECK, LIGHT_FRICTION_NECK = 0.05, 0.01
LIGHT_DAMPING_WRIST, LIGHT_DAMPING_FINGER = 0.002, 1e-5

# (finger, base on the palm (x, z), spread axis or None, [(length, radius, mass) per phalanx],
#  flexion joint names)
FINGERS_32 = [("index", (0.0, -PALM[2]), None, [(0.04, 0.009, 0.012), (0.03, 0.009, 0.009),
                                               (0.025, 0.009, 0.006)], ["mcp", "pip", "dip"])]
_F = [(0.04, 0.009, 0.012), (0.03, 0.009, 0.009), (0.025, 0.009, 0.006)]
FINGERS_64 = [
    ("thumb", (0.035, -0.03), (0, 0, 1), [(0.035, 0.01, 0.012), (0.03, 0.01, 0.009)], ["mcp", "ip"]),
    ("index", (0.026, -PALM[2]), (0, 1, 0), _F, ["mcp", "pip", "dip"]),
    ("middle", (0.009, -PALM[2]), (0, 1, 0), _F, ["mcp", "pip", "dip"]),
    ("ring", (-0.009, -PALM[2]), (0, 1, 0), _F, ["mcp", "pip", "dip"]),
    ("little", (-0.026, -PALM[2]), (0, 1, 0), _F, ["mcp", "pip", "dip"]),
]

# Bookkeeping for the gains: every link of a variant's added subtrees with its parent, the origin
# of its joint in the parent's frame and its inertial (all joint angles 0, no rotations).
tree = {}  # link -> (parent link, joint, xyz, axis)
bodies = {}  # link -> (mass, com, (ixx, iyy, izz))
extra_joints = []  # (joint, child link, class)


def track(child, jname, xyz, axis, parent, cls="neck"):
    tree[child] = (parent, jname, xyz, axis)
    extra_joints.append((jname, child, cls))


def body_info(name, m, com, inertia):
    bodies[name] = (m, com, inertia)


def origin_of(name):  # link frame in the frame of the first untracked ancestor
    p = [0.0, 0.0, 0.0]
    while name in tree:
        parent, _, xyz, _ = tree[name]
        p = [a + b for a, b in zip(p, xyz)]
        name = parent
    return p


def subtree(name):
    return [l for l in bodies if l == name or _below(l, name)]


def _below(link, ancestor):
    while link in tree:
        link = tree[link][0]
        if link == ancestor:
            return True
    return False


def _cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _dot(a, b):
    return sum(x * y for x, y in zip(a, b))


def _inverse(a):  # Gauss-Jordan with partial pivoting (no numpy needed)
    n = len(a)
    m = [row[:] + [1.0 if i == j else 0.0 for j in range(n)] for i, row in enumerate(a)]
    for c in range(n):
        p = max(range(c, n), key=lambda r: abs(m[r][c]))
        m[c], m[p] = m[p], m[c]
        piv = m[c][c]
        m[c] = [x / piv for x in m[c]]
        for r in range(n):
            if r != c and m[r][c] != 0.0:
                f = m[r][c]
                m[r] = [x - f * y for x, y in zip(m[r], m[c])]
    return [row[n:] for row in m]


def effective_inertias(root):
    """Effective inertia 1 / (M^-1)_jj of each added joint whose subtree hangs from `root` (a link
    held fixed: the forearm, the torso), M the joint-space inertia matrix of those joints with all
    angles 0. In a chain this is much less than M_jj (the subtree's inertia about the axis, which
    counts the links beyond as rigidly attached): 8e-6 against 7.6e-5 kg m^2 for a finger's first
    flexion joint. An explicit PD at period dt is stable on a joint for kd dt / I < 2 with I this
    effective inertia, not M_jj."""
    joints = [(j, c) for j, c, _ in extra_joints if c == root or _below(c, root)
              or tree[c][0] == root]
    cols = []  # (joint axis, joint position) in the root frame
    for _, c in joints:
        cols.append((tree[c][3], origin_of(c)))
    n = len(joints)
    M = [[0.0] * n for _ in range(n)]
    for l, (m, com, (ixx, iyy, izz)) in bodies.items():
        x = [a + b for a, b in zip(origin_of(l), com)]
        moved = [i for i, (_, c) in enumerate(joints) if l == c or _below(l, c)]
        for i in moved:
            ai, pi = cols[i]
            vi = _cross(ai, [a - b for a, b in zip(x, pi)])
            for j in moved:
                aj, pj = cols[j]
                vj = _cross(aj, [a - b for a, b in zip(x, pj)])
                M[i][j] += (ixx * ai[0] * aj[0] + iyy * ai[1] * aj[1] + izz * ai[2] * aj[2]
                            + m * _dot(vi, vj))
    Minv = _inverse(M)
    return {j: 1.0 / Minv[i][i] for i, (j, _) in enumerate(joints)}


def extra_gains():
    """PD gains of the added joints from their effective inertia I (effective_inertias):
    kp = I wn^2, kd = 2 I wn, critically damped at wn = 100 rad/s: kp dt^2 / I = 0.01 and
    kd dt / I = 0.2 at 1 kHz, well inside the explicit PD's stability bound and the safety
    layer's start-up bound (components/safety: kp <= 0.2 I / dt^2, kd <= 0.5 I / dt)."""
    eff = {}
    for root in ("torso", "l_forearm", "r_forearm"):
        eff.update(effective_inertias(root))
    g = []
    for jname, _, _ in extra_joints:
        inertia = eff[jname]
        g.append((jname, float(f"{inertia * WN * WN:.2g}"), float(f"{2 * inertia * WN:.2g}"), inertia))
    return g


def hand_variant(side, s):
    fingers = FINGERS_32 if NJ == 32 else FINGERS_64
    m_fingers = sum(KNUCKLE_M if spread else 0.0 for _, _, spread, _, _ in fingers)
    m_fingers += sum(ph[2] for _, _, _, phal, _ in fingers for ph in phal)
    m_palm = HAND_M - 2 * WRIST_LINK_M - m_fingers
    wl, wr = WRIST_LINK_M, WRIST_LINK_R
    parent = f"{side}_forearm"
    for jn, ax, lim in (("wrist_yaw", (0, 0, 1), 1.5), ("wrist_pitch", (0, 1, 0), 1.2),
                        ("wrist_roll", (1, 0, 0), 0.8)):
        child = f"{side}_hand" if jn == "wrist_roll" else f"{side}_{jn}_link"
        xyz = (0, 0, -FOREARM) if jn == "wrist_yaw" else (0, 0, 0)
        joint(f"{side}_{jn}", "revolute", parent, child, xyz, ax, -lim, lim, 5, 10,
              dyn=(LIGHT_DAMPING_WRIST, 0.0))
        track(child, f"{side}_{jn}", xyz, ax, parent, "wrist")
        if jn != "wrist_roll":
            link(child, wl, (0, 0, 0), sphere_inertia(wl, wr), sphere(wr))
            body_info(child, wl, (0, 0, 0), sphere_inertia(wl, wr))
        parent = child
    com = (0, 0, -PALM[2] / 2)
    link(f"{side}_hand", m_palm, com, box_inertia(m_palm, *PALM), box(*PALM), com)
    body_info(f"{side}_hand", m_palm, com, box_inertia(m_palm, *PALM))
    for finger, (bx, bz), spread, phalanges, names in fingers:
        parent, xyz = f"{side}_hand", (bx, 0, bz)
        if spread is not None:
            child = f"{side}_{finger}_knuckle"
            jn = f"{side}_{finger}_{'rot' if finger == 'thumb' else 'abd'}"
            lim = 0.8 if finger == "thumb" else 0.35
            joint(jn, "revolute", parent, child, xyz, spread, -lim, lim, 0.5, 10,
                  dyn=(LIGHT_DAMPING_FINGER, 0.0))
            track(child, jn, xyz, spread, parent, "finger")
            link(child, KNUCKLE_M, (0, 0, 0), sphere_inertia(KNUCKLE_M, KNUCKLE_R), sphere(KNUCKLE_R))
            body_info(child, KNUCKLE_M, (0, 0, 0), sphere_inertia(KNUCKLE_M, KNUCKLE_R))
            parent, xyz = child, (0, 0, 0)
        # flexion curls the finger towards the palm's inner face (towards the body: -y on the
        # left hand, +y on the right), positive angles
        ax = (-s, 0, 0)
        for k, ((length, r, m), nm) in enumerate(zip(phalanges, names)):
            child = f"{side}_{finger}_{k + 1}"
            jn = f"{side}_{finger}_{nm}"
            joint(jn, "revolute", parent, child, xyz, ax, -0.2, 1.6, 0.5, 10,
                  dyn=(LIGHT_DAMPING_FINGER, 0.0))
            track(child, jn, xyz, ax, parent, "finger")
            c = (0, 0, -length / 2)
            link(child, m, c, cyl_inertia(m, r, length), cyl(r, length), c)
            body_info(child, m, c, cyl_inertia(m, r, length))
            parent, xyz = child, (0, 0, -length)


def robot_yaml():
    upper = ["torso_yaw", "l_shoulder_pitch", "l_shoulder_roll", "l_elbow",
             "r_shoulder_pitch", "r_shoulder_roll", "r_elbow"] + [j for j, _, _ in extra_joints]
    lines = ["  upper_body: ["]
    for k, j in enumerate(upper):
        item = j + ("]" if k + 1 == len(upper) else ",")
        if len(lines[-1]) + len(item) > 98:
            lines.append("              ")
        lines[-1] += ("" if lines[-1].endswith("[") else " ") + item
    gains = "\n".join(f"  {j}: {{kp: {kp:g}, kd: {kd:g}}}   # I = {i:.3g} kg m^2"
                      for j, kp, kd, i in extra_gains())
    with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "robot.yaml")) as fh:
        base = fh.read()
    # The base robot's file with this robot's name, URDF, upper-body joints and added gains.
    y = base.replace("# Robot configuration of the project's humanoid (schema: deploy/robots/README.md).",
                     f"# Generated by poise_humanoid/generate_urdf.py --joints {NJ}; edit the script, not this file.\n"
                     f"# The project's humanoid with {NJ} joints (deploy/robots/README.md); schema: "
                     "deploy/robots/README.md.")
    y = y.replace("name: poise_humanoid\n", f"name: {NAME}\n")
    y = y.replace("urdf: poise_humanoid.urdf ", f"urdf: {NAME}.urdf ")
    old_upper = ("  upper_body: [torso_yaw, l_shoulder_pitch, l_shoulder_roll, l_elbow,\n"
                 "               r_shoulder_pitch, r_shoulder_roll, r_elbow]")
    assert old_upper in y
    y = y.replace(old_upper, "\n".join(lines))
    y = y.rstrip("\n") + ("\n  # Added joints (generate_urdf.py extra_gains): kp = I wn^2, kd = 2 I wn, "
                          "wn = 100 rad/s,\n  # I = effective inertia 1 / (M^-1)_jj of the joint, "
                          "the rest of its hand (or the head) free.\n"
                          + gains + "\n")
    return y


ap = argparse.ArgumentParser(description="Writes the poise humanoid's URDF (and a variant's robot.yaml).")
ap.add_argument("--joints", type=int, choices=(19, 32, 64), default=19,
                help="non-fixed joints: 19 = the project's humanoid (default), 32 or 64 = variants")
ap.add_argument("--out", help="output folder (default: this folder for 19, ../poise_humanoid_N/ else)")
args = ap.parse_args()
NJ = args.joints
NAME = "poise_humanoid" if NJ == 19 else f"poise_humanoid_{NJ}"
VARIANT = NJ != 19

out.append('<?xml version="1.0"?>')
if VARIANT:
    out.append(f"<!-- Generated by generate_urdf.py --joints {NJ}; edit the script, not this file. -->")
else:
    out.append("<!-- Generated by generate_urdf.py; edit the script, not this file. -->")
out.append(f'<robot name="{NAME}">')

# --- pelvis (floating base), IMU ------------------------------------------------------------
m = 8.0
dims = (0.18, 0.26, 0.14)
link("pelvis", m, (0, 0, -0.02), box_inertia(m, *dims), box(*dims), (0, 0, -0.02))
link("imu_link")  # massless sensor frame
joint("imu_joint", "fixed", "pelvis", "imu_link", (-0.04, 0.0, 0.04))

# --- torso and head -------------------------------------------------------------------------
m = 14.0
dims = (0.20, 0.32, 0.40)
joint("torso_yaw", "revolute", "pelvis", "torso", (0, 0, TORSO_Z), (0, 0, 1), -0.8, 0.8, 100, 4)
link("torso", m, (0, 0, 0.22), box_inertia(m, *dims), box(*dims), (0, 0, 0.22))
m = 3.0
r = 0.085
if VARIANT:
    joint("neck_yaw", "revolute", "torso", "head", (0, 0, 0.42), (0, 0, 1), -1.2, 1.2, 10, 6,
          dyn=(LIGHT_DAMPING_NECK, LIGHT_FRICTION_NECK))
    track("head", "neck_yaw", (0, 0, 0.42), (0, 0, 1), "torso")
else:
    joint("neck_fixed", "fixed", "torso", "head", (0, 0, 0.42))
link("head", m, (0, 0, 0.04), sphere_inertia(m, r), sphere(r), (0, 0, 0.04))
body_info("head", m, (0, 0, 0.04), sphere_inertia(m, r))

# --- arms -----------------------------------------------------------------------------------
for side, s in (("l", 1.0), ("r", -1.0)):
    joint(f"{side}_shoulder_pitch", "revolute", "torso", f"{side}_shoulder_link",
          (SHOULDER[0], s * SHOULDER[1], SHOULDER[2]), (0, 1, 0), -3.0, 1.0, 40, 6)
    m, r = 0.3, 0.04
    link(f"{side}_shoulder_link", m, (0, 0, 0), sphere_inertia(m, r), sphere(r))
    lo, hi = (-0.2, 2.5) if s > 0 else (-2.5, 0.2)
    joint(f"{side}_shoulder_roll", "revolute", f"{side}_shoulder_link", f"{side}_upper_arm",
          (0, 0, 0), (1, 0, 0), lo, hi, 40, 6)
    m, r = 1.5, 0.04
    link(f"{side}_upper_arm", m, (0, 0, -UPPER_ARM / 2), cyl_inertia(m, r, UPPER_ARM),
         cyl(r, UPPER_ARM), (0, 0, -UPPER_ARM / 2))
    joint(f"{side}_elbow", "revolute", f"{side}_upper_arm", f"{side}_forearm",
          (0, 0, -UPPER_ARM), (0, 1, 0), -2.4, 0.0, 30, 6)
    m, r = 0.8, 0.035
    link(f"{side}_forearm", m, (0, 0, -FOREARM / 2), cyl_inertia(m, r, FOREARM),
         cyl(r, FOREARM), (0, 0, -FOREARM / 2))
    if VARIANT:
        hand_variant(side, s)
        continue
    joint(f"{side}_wrist_fixed", "fixed", f"{side}_forearm", f"{side}_hand", (0, 0, -FOREARM))
    m, r = 0.3, 0.04
    link(f"{side}_hand", m, (0, 0, -0.04), sphere_inertia(m, r), sphere(r), (0, 0, -0.04))

# --- legs -----------------------------------------------------------------------------------
for side, s in (("l", 1.0), ("r", -1.0)):
    joint(f"{side}_hip_yaw", "revolute", "pelvis", f"{side}_hip_yaw_link",
          (0, s * HIP_Y, HIP_YAW_Z), (0, 0, 1), -0.6, 0.6, 80, 8)
    m, r, h = 0.5, 0.05, 0.05
    link(f"{side}_hip_yaw_link", m, (0, 0, -0.025), cyl_inertia(m, r, h), cyl(r, h), (0, 0, -0.025))
    lo, hi = (-0.35, 0.6) if s > 0 else (-0.6, 0.35)
    joint(f"{side}_hip_roll", "revolute", f"{side}_hip_yaw_link", f"{side}_hip_roll_link",
          (0, 0, HIP_ROLL_Z), (1, 0, 0), lo, hi, 120, 8)
    m, r = 0.5, 0.05
    link(f"{side}_hip_roll_link", m, (0, 0, 0), sphere_inertia(m, r), sphere(r))
    joint(f"{side}_hip_pitch", "revolute", f"{side}_hip_roll_link", f"{side}_thigh",
          (0, 0, 0), (0, 1, 0), -2.0, 0.6, 150, 8)
    m, r = 4.5, 0.06
    link(f"{side}_thigh", m, (0, 0, -THIGH / 2), cyl_inertia(m, r, THIGH), cyl(r, THIGH),
         (0, 0, -THIGH / 2))
    joint(f"{side}_knee", "revolute", f"{side}_thigh", f"{side}_shank", (0, 0, -THIGH),
          (0, 1, 0), 0.0, 2.4, 150, 10)
    m, r = 3.0, 0.05
    link(f"{side}_shank", m, (0, 0, -SHANK / 2), cyl_inertia(m, r, SHANK), cyl(r, SHANK),
         (0, 0, -SHANK / 2))
    joint(f"{side}_ankle_pitch", "revolute", f"{side}_shank", f"{side}_ankle_link",
          (0, 0, -SHANK), (0, 1, 0), -1.0, 0.8, 80, 10)
    m, r = 0.3, 0.03
    link(f"{side}_ankle_link", m, (0, 0, 0), sphere_inertia(m, r), sphere(r))
    joint(f"{side}_ankle_roll", "revolute", f"{side}_ankle_link", f"{side}_foot", (0, 0, 0),
          (1, 0, 0), -0.4, 0.4, 50, 10)
    m = 1.2
    lx = FOOT_X[1] - FOOT_X[0]
    cx = 0.5 * (FOOT_X[0] + FOOT_X[1])
    cz = -ANKLE_HEIGHT + FOOT_T / 2
    link(f"{side}_foot", m, (cx, 0, cz), box_inertia(m, lx, FOOT_W, FOOT_T),
         box(lx, FOOT_W, FOOT_T), (cx, 0, cz))
    # Sole frame: on the sole plane, straight below the ankle, axes aligned with the foot.
    joint(f"{side}_sole_joint", "fixed", f"{side}_foot", f"{side}_sole", (0, 0, -ANKLE_HEIGHT))
    link(f"{side}_sole")

out.append("</robot>")

here = os.path.dirname(os.path.abspath(__file__))
folder = args.out or (here if not VARIANT else os.path.join(os.path.dirname(here), NAME))
os.makedirs(folder, exist_ok=True)
path = os.path.join(folder, f"{NAME}.urdf")
with open(path, "w") as fh:
    fh.write("\n".join(out) + "\n")
print(f"wrote {path}")
if VARIANT:
    n = 19 + len(extra_joints)
    assert n == NJ, f"{n} joints, wanted {NJ}"
    path = os.path.join(folder, "robot.yaml")
    with open(path, "w") as fh:
        fh.write(robot_yaml())
    print(f"wrote {path}")
