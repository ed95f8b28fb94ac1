"""A suite of MJCF arms of the kinds users bring (written here, for the tests), and files that must be refused.

`write_suite(folder)` writes them and returns (name, path, refusal) triples: refusal is None for an arm every
command must run, else a regular expression the one-line refusal must match.
"""

from __future__ import annotations

from pathlib import Path

ASSETS = Path(__file__).resolve().parent.parent / "assets"


def chain(name: str, links: list[tuple[str, str, float, float]], *, head: str = "", defaults: str = "",
          extra_world: str = "", tail: str = "", joint_extra: str = "", actuators: str = "", site: bool = True,
          compiler: str = '<compiler angle="radian"/>') -> str:
    """An open chain: each link (joint axis "x y z", range "lo hi" or "", length m, mass kg) hangs from the
    last, along z."""
    body = ""
    close = ""
    for k, (axis, rng, length, mass) in enumerate(links):
        limit = f' range="{rng}"' if rng else ""
        body += (f'<body name="link{k}" pos="0 0 {0.1 if k == 0 else links[k - 1][2]}">'
                 f'<joint name="j{k}" axis="{axis}"{limit} actuatorfrcrange="-40 40"{joint_extra}/>'
                 f'<geom type="capsule" fromto="0 0 0 0 0 {length}" size="0.03" mass="{mass}"/>')
        close += "</body>"
    if site:
        body += f'<site name="attachment_site" pos="0 0 {links[-1][2]}"/>'
    return (f'<mujoco model="{name}">{compiler}{head}<default>{defaults}</default>'
            f'<worldbody>{extra_world}{body}{close}</worldbody>{actuators}{tail}</mujoco>')


FINGERS = ('<body name="hand" pos="0 0 0.35"><geom type="box" size="0.04 0.02 0.02" mass="0.3"/>'
           '<body name="left" pos="0.02 0 0.04"><joint name="finger_left" type="slide" axis="1 0 0" range="0 0.04"/>'
           '<geom type="box" size="0.005 0.01 0.03" mass="0.05"/></body>'
           '<body name="right" pos="-0.02 0 0.04"><joint name="finger_right" type="slide" axis="-1 0 0" '
           'range="0 0.04"/><geom type="box" size="0.005 0.01 0.03" mass="0.05"/></body></body>')
"""A two-finger gripper of slide joints, as makers ship their arms (coupled by an equality in the files that
use it)."""
THREE = [("0 0 1", "-3 3", 0.1, 2.0), ("0 1 0", "-2 2", 0.4, 1.5), ("0 1 0", "-2.5 2.5", 0.35, 1.0)]
SIX = [*THREE, ("0 1 0", "-3 3", 0.1, 0.6), ("0 0 1", "-3 3", 0.1, 0.4), ("0 1 0", "-3 3", 0.08, 0.3)]
SEVEN = [("0 0 1", "-3 3", 0.15, 3.0), ("0 1 0", "-2 2", 0.1, 3.0), ("0 0 1", "-3 3", 0.3, 2.0),
         ("0 1 0", "-2.5 2.5", 0.1, 1.5), ("0 0 1", "-3 3", 0.25, 1.0), ("0 1 0", "-2 2", 0.08, 0.5),
         ("0 0 1", "-3 3", 0.06, 0.3)]


def _servos(links: list[tuple[str, str, float, float]], kind: str) -> str:
    """Position servos on every joint as makers write them: `general` (an affine bias, gain kp, bias -kp q - kv
    qd), `dampratio` (`position` with kp and a damping ratio) or `inheritrange` (`position` whose control range is
    the joint's); force ranges of 40 N m on the first three joints, 10 on the wrist."""
    out = "<actuator>"
    for k in range(len(links)):
        force = 40 if k < 3 else 10
        if kind == "general":
            out += (f'<general name="a{k}" joint="j{k}" gaintype="fixed" biastype="affine" gainprm="200" '
                    f'biasprm="0 -200 -20" forcerange="-{force} {force}"/>')
        elif kind == "dampratio":
            out += f'<position name="a{k}" joint="j{k}" kp="200" dampratio="1" forcerange="-{force} {force}"/>'
        else:
            out += f'<position name="a{k}" joint="j{k}" kp="200" inheritrange="1" forcerange="-{force} {force}"/>'
    return out + "</actuator>"
TWO = [("0 1 0", "-2.5 2.5", 0.4, 1.0), ("0 1 0", "-2.5 2.5", 0.3, 0.6)]
SERVOS = ('<actuator><position name="s0" joint="j0" kp="200" forcerange="-40 40"/>'
          '<position name="s1" joint="j1" kp="200" forcerange="-40 40"/>'
          '<position name="s2" joint="j2" kp="200" forcerange="-30 30"/></actuator>')

OBJ = """v 0 0 0
v 0.05 0 0
v 0 0.05 0
v 0 0 0.05
f 1 3 2
f 1 2 4
f 1 4 3
f 2 3 4
"""


def write_suite(folder: Path) -> list[tuple[str, Path, str | None]]:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "tetra.obj").write_text(OBJ)
    (folder / "links.xml").write_text(
        "<mujoco><body name=\"inc_link\" pos=\"0 0 0.1\"><joint name=\"ij0\" axis=\"0 0 1\" range=\"-3 3\" "
        "actuatorfrcrange=\"-30 30\"/><geom type=\"capsule\" fromto=\"0 0 0 0.3 0 0\" size=\"0.03\" mass=\"1\"/>"
        "<body name=\"inc_link2\" pos=\"0.3 0 0\"><joint name=\"ij1\" axis=\"0 1 0\" range=\"-2 2\" "
        "actuatorfrcrange=\"-20 20\"/><geom type=\"capsule\" fromto=\"0 0 0 0.3 0 0\" size=\"0.02\" mass=\"0.5\"/>"
        "</body></body></mujoco>")
    arms: dict[str, tuple[str, str | None]] = {
        "plain_three": (chain("plain_three", THREE), None),
        "menagerie_servos": (chain("menagerie_servos", THREE, actuators=SERVOS), None),
        "no_cameras_no_site": (chain("no_cameras_no_site", THREE, site=False), None),
        "defaults_childclass": (chain("defaults_childclass", THREE, defaults=(
            '<default class="arm"><joint damping="0.5" armature="0.01"/><geom rgba="0.2 0.4 0.8 1"/></default>'
            '<motor gear="30" ctrlrange="-1 1"/>'), actuators=(
            '<actuator><motor joint="j0" name="m0"/><motor joint="j1" name="m1"/><motor joint="j2" name="m2"/>'
            '</actuator>')).replace('<body name="link0"', '<body name="link0" childclass="arm"'), None),
        "fixed_gripper": (chain("fixed_gripper", THREE).replace(
            '<site name="attachment_site"',
            '<body name="gripper" pos="0 0 0.35"><geom type="box" size="0.04 0.02 0.02" mass="0.3"/>'
            '<body name="finger" pos="0.03 0 0.04"><geom type="box" size="0.005 0.01 0.03" mass="0.05"/></body>'
            '</body><site name="attachment_site"'), None),
        "continuous_base": (chain("continuous_base", [("0 0 1", "", 0.1, 2.0), *THREE[1:]]), None),
        "geared_motors": (chain("geared_motors", THREE, actuators=(
            '<actuator><motor joint="j0" name="m0" gear="100" ctrlrange="-0.5 0.5"/>'
            '<motor joint="j1" name="m1" gear="100" ctrlrange="-0.4 0.4"/>'
            '<motor joint="j2" name="m2" gear="50" ctrlrange="-0.5 0.5"/></actuator>')), None),
        "sensors_keyframe": (chain("sensors_keyframe", THREE, actuators=SERVOS, tail=(
            '<sensor><jointpos joint="j1" name="p1"/><actuatorfrc actuator="s0" name="f0"/>'
            '<framepos objtype="site" objname="attachment_site" name="tip"/></sensor>'
            '<keyframe><key name="home" qpos="0 0.3 -0.6" ctrl="0 0.3 -0.6"/></keyframe>')), None),
        "passive_friction": (chain("passive_friction", THREE, joint_extra=' damping="1" frictionloss="1.5"'), None),
        "scene_table_contacts": (chain("scene_table_contacts", THREE, extra_world=(
            '<light pos="0 0 3"/><geom name="floor" type="plane" size="2 2 0.1"/>'
            '<body name="table" pos="0.6 0 0.3"><geom type="box" size="0.3 0.3 0.02"/></body>'
            '<camera name="overview" pos="1.5 -1.5 1.2" xyaxes="1 1 0 -0.4 0.4 1"/>')), None),
        "include": ('<mujoco model="include"><compiler angle="radian"/><worldbody><include file="links.xml"/>'
                    '</worldbody></mujoco>', None),
        "meshes": (chain("meshes", THREE, head='<asset><mesh name="tetra" file="tetra.obj"/></asset>').replace(
            '<site name="attachment_site"', '<geom type="mesh" mesh="tetra" mass="0.2"/><site name="attachment_site"'),
            None),
        "degrees_home": (chain("degrees_home", [("0 0 1", "-170 170", 0.1, 2.0), ("0 1 0", "-110 110", 0.4, 1.5),
                                               ("0 1 0", "-140 140", 0.35, 1.0)], compiler="",
                               tail='<keyframe><key name="home" qpos="0.3 -0.5 0.8"/></keyframe>'), None),
        "narrow_ranges": (chain("narrow_ranges", [("0 0 1", "-0.3 0.3", 0.1, 2.0), ("0 1 0", "-0.2 0.6", 0.4, 1.5),
                                                  ("0 1 0", "0 0.4", 0.35, 1.0)]), None),
        "four_dof": (chain("four_dof", [*THREE, ("1 0 0", "-2 2", 0.15, 0.4)]), None),
        "two_dof_vertical": (chain("two_dof_vertical", TWO), None),
        "heavy_armature_damping": (chain("heavy_armature_damping", THREE,
                                         joint_extra=' damping="40" armature="0.2"'), None),
        "light_stretched_home": (chain("light_stretched_home", [("0 0 1", "-3 3", 0.05, 0.1),
                                                                ("0 1 0", "-1.5 1.5", 0.3, 0.1),
                                                                ("0 1 0", "-2.8 2.8", 0.3, 0.3)],
                                       tail='<keyframe><key name="home" qpos="0 1.4 0"/></keyframe>'), None),
        "unnamed": (chain("unnamed", THREE).replace(' name="link1"', "").replace(' name="j2"', ""), None),
        "rotated_base": (chain("rotated_base", THREE).replace(
            '<body name="link0" pos="0 0 0.1">', '<body name="link0" pos="0.2 0.1 0.1" quat="0.92 0 0 0.38">'), None),
        "body_named_payload": (chain("body_named_payload", THREE).replace(
            '<site name="attachment_site"', '<body name="payload" pos="0 0 0.35"><geom type="sphere" size="0.03" '
            'mass="0.2"/></body><site name="attachment_site"'), None),
        "gripper_fingers": (chain("gripper_fingers", THREE, tail=(
            '<equality><joint joint1="finger_left" joint2="finger_right"/></equality>'
            '<keyframe><key name="home" qpos="0 0.3 -0.6 0.02 0.02"/></keyframe>'),
            actuators='<actuator><position name="grip" joint="finger_left" kp="100" ctrlrange="0 0.04"/></actuator>'
            ).replace('<site name="attachment_site"', FINGERS + '<site name="attachment_site"'), None),
        "urdf": ("", None),
        # in the conventions of makers' files (Menagerie and their own): servos, friction, damping, 6 and 7 hinges
        "maker_general_affine_six": (chain("maker_general_affine_six", SIX, joint_extra=' armature="0.05"',
                                           actuators=_servos(SIX, "general")), None),
        "maker_position_dampratio": (chain("maker_position_dampratio", THREE, joint_extra=' armature="0.02"',
                                           actuators=_servos(THREE, "dampratio")), None),
        "maker_inheritrange": (chain("maker_inheritrange", THREE, joint_extra=' armature="0.02"',
                                     actuators=_servos(THREE, "inheritrange")), None),
        "maker_seven_actuatorfrcrange": (chain("maker_seven_actuatorfrcrange", SEVEN,
                                               joint_extra=' armature="0.03" damping="0.5"'), None),
        "maker_friction_one_newton": (chain("maker_friction_one_newton", SIX,
                                            joint_extra=' armature="0.05" damping="1" frictionloss="1"',
                                            actuators=_servos(SIX, "general")), None),
        "maker_heavy_damping_light_links": (chain("maker_heavy_damping_light_links", [
            *THREE, ("1 0 0", "-2 2", 0.08, 0.2), ("0 1 0", "-2 2", 0.06, 0.1)], joint_extra=' damping="20"'), None),
        "maker_seven_gripper": (chain("maker_seven_gripper", SEVEN, joint_extra=' armature="0.03" frictionloss="1"',
                                      tail=('<equality><joint joint1="finger_left" joint2="finger_right"/></equality>'
                                            '<keyframe><key name="home" qpos="0 0.3 0 -0.6 0 0.4 0 0.02 0.02"/>'
                                            '</keyframe>'),
                                      actuators=_servos(SEVEN, "general")[:-len("</actuator>")]
                                      + '<position name="grip" joint="finger_left" kp="100" ctrlrange="0 0.04"/>'
                                        '</actuator>').replace('<site name="attachment_site"',
                                                               FINGERS + '<site name="attachment_site"'), None),
        "maker_continuous_wrist": (chain("maker_continuous_wrist", [*SIX[:5], ("0 0 1", "", 0.05, 0.2)],
                                         joint_extra=' armature="0.05" frictionloss="1"'), None),
        # refused
        "slide_joint": (chain("slide_joint", THREE).replace('<joint name="j1" axis="0 1 0"',
                                                            '<joint name="j1" type="slide" axis="0 1 0"'),
                        r"joint 'j1' is a slide joint; mjtraj plans arms of hinge joints only"),
        "finger_coupled_to_the_arm": (chain("finger_coupled_to_the_arm", THREE, tail=(
            '<equality><joint joint1="finger_left" joint2="j2"/></equality>')).replace(
            '<site name="attachment_site"', FINGERS + '<site name="attachment_site"'),
            r"equality constraint '\(unnamed\)': equality constraints are not supported"),
        "tendon": (chain("tendon", THREE, tail='<tendon><fixed name="coupling"><joint joint="j1" coef="1"/>'
                                               '<joint joint="j2" coef="-1"/></fixed></tendon>'),
                   r"tendon 'coupling': tendons are not supported"),
        "free_object": (chain("free_object", THREE, extra_world=(
            '<body name="box" pos="1 0 0.5"><freejoint name="box_free"/><geom type="box" size="0.05 0.05 0.05" '
            'mass="0.1"/></body>')), r"joint 'box_free' is a free joint"),
        "missing_mesh": (chain("missing_mesh", THREE, head='<asset><mesh name="m" file="nowhere.stl"/></asset>')
                         .replace('<site name="attachment_site"', '<geom type="mesh" mesh="m"/>'
                                  '<site name="attachment_site"'), r"nowhere\.stl"),
        "not_xml": ("this is not an MJCF file\n", r"cannot load model"),
    }
    out = []
    for name, (text, refusal) in arms.items():
        path = folder / f"{name}.{'urdf' if name == 'urdf' else 'xml'}"
        path.write_text(URDF if name == "urdf" else text)
        out.append((name, path, refusal))
    out.append(("shipped_planar_2link", ASSETS / "planar_2link.xml", None))
    out.append(("shipped_ur5_6dof", ASSETS / "ur5_6dof.xml", None))
    return out


URDF = """<?xml version="1.0"?>
<robot name="urdf_arm">
  <link name="base"><inertial><mass value="2"/><inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>
  </inertial></link>
  <link name="upper"><inertial><origin xyz="0 0 0.2"/><mass value="1.5"/>
    <inertia ixx="0.02" ixy="0" ixz="0" iyy="0.02" iyz="0" izz="0.002"/></inertial></link>
  <link name="fore"><inertial><origin xyz="0 0 0.15"/><mass value="1"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.001"/></inertial></link>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/><origin xyz="0 0 0.1"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="40" velocity="3"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="fore"/><origin xyz="0 0 0.4"/>
    <axis xyz="0 1 0"/><limit lower="-2.5" upper="2.5" effort="30" velocity="3"/></joint>
</robot>
"""
