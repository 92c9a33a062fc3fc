"""The camera path: the iCub's eye looks at a screen showing the stimulus pair, in pybullet.

Scene (pybullet DIRECT, TinyRenderer, world frame = the robot's ``root_link``: x backwards,
y to the robot's right, z up):

* the iCub from the ``icub-models`` package, fixed at its root link, torso and neck at zero;
* a flat screen ``screen_distance`` metres in front of the eyes, centred at eye height, showing
  the pair image as a texture (target on one side, rotated object on the other);
* the eye camera.  The package's URDFs stop at the head (no eye joints), so the eye stage of the
  iCub head is appended to the URDF: an ``eyes_tilt`` joint and ``l_eye_pan`` / ``r_eye_pan``
  joints, 5.4 cm in front of and 11 cm above the neck-yaw joint, eyes 6.8 cm apart
  (approximately the iCub's published eye kinematics).  The camera pose is the eye link's pose
  from pytorch-kinematics forward kinematics of the chain root_link -> torso -> neck -> eye.

Gaze is hard-wired: the eye tilt and pan that point the optical axis at each object's centre
are computed once from the chain (no learning), the target first, then the rotated object.
Rendering uses ambient light only, so the screen shows its pixels as drawn; luminance and
noise are applied afterwards by the eye (see :mod:`neuroimagery.vision.eye`).
"""
from __future__ import annotations

import os
import re
import tempfile
import xml.etree.ElementTree as ET
from functools import lru_cache

import cv2
import numpy as np
import torch

from neuroimagery.vision.shapes import BACKGROUND_BGR
from neuroimagery.core.native import quiet_native_output

__all__ = ["icub_urdf_with_eyes", "head_eye_urdf", "eye_chain", "CameraScene"]

EYE_FORWARD = 0.054  # m, eye centres in front of the neck-yaw joint (head frame z)
EYE_UP = 0.11  # m, eye centres above the neck-yaw joint (head frame y)
EYE_HALF_BASELINE = 0.034  # m, half the distance between the eyes (head frame x = robot's left)
TEXTURE_SCALE = 2  # a stimulus texture has this many pixels per pixel of the drawn stimulus

_TOKEN_INERTIAL = ('<inertial><mass value="0.001"/><origin xyz="0 0 0"/>'
                   '<inertia ixx="1e-7" ixy="0" ixz="0" iyy="1e-7" iyz="0" izz="1e-7"/></inertial>')
_EYE_XML = """
  <link name="eyes_tilt_link">
    <inertial><mass value="0.01"/><origin xyz="0 0 0"/>
      <inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial>
  </link>
  <joint name="eyes_tilt" type="revolute">
    <origin xyz="0 {up} {fwd}" rpy="0 0 0"/>
    <axis xyz="-1 0 0"/>
    <parent link="head"/><child link="eyes_tilt_link"/>
    <limit effort="10" lower="-0.61" upper="0.52" velocity="10"/>
  </joint>
  <link name="l_eye">
    <inertial><mass value="0.01"/><origin xyz="0 0 0"/>
      <inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial>
  </link>
  <joint name="l_eye_pan" type="revolute">
    <origin xyz="{half} 0 0" rpy="0 0 0"/>
    <axis xyz="0 1 0"/>
    <parent link="eyes_tilt_link"/><child link="l_eye"/>
    <limit effort="10" lower="-0.87" upper="0.87" velocity="10"/>
  </joint>
  <link name="r_eye">
    <inertial><mass value="0.01"/><origin xyz="0 0 0"/>
      <inertia ixx="1e-6" ixy="0" ixz="0" iyy="1e-6" iyz="0" izz="1e-6"/></inertial>
  </link>
  <joint name="r_eye_pan" type="revolute">
    <origin xyz="-{half} 0 0" rpy="0 0 0"/>
    <axis xyz="0 1 0"/>
    <parent link="eyes_tilt_link"/><child link="r_eye"/>
    <limit effort="10" lower="-0.87" upper="0.87" velocity="10"/>
  </joint>
"""


@lru_cache(maxsize=4)
def icub_urdf_with_eyes(robot_model: str = "iCubGazeboV2_5", meshes: bool = False) -> str:
    """The icub-models URDF text with eye joints appended.

    Without ``meshes`` the visual and collision elements are dropped (the eye camera sits inside
    the head shell, and kinematics needs none of them); gazebo/sensor extensions are dropped
    always.
    """
    import icub_models

    path = icub_models.get_model_file(robot_model)
    if path is None or not os.path.exists(str(path)):
        raise ValueError(f"vision.robot_model {robot_model!r} is not in icub-models")
    text = open(path, encoding="utf-8").read()
    text = re.sub(r"<gazebo\b.*?</gazebo>", "", text, flags=re.S)
    text = re.sub(r"<sensor\b.*?</sensor>", "", text, flags=re.S)
    if not meshes:
        text = re.sub(r"<visual\b.*?</visual>", "", text, flags=re.S)
        text = re.sub(r"<collision\b.*?</collision>", "", text, flags=re.S)
    # frame-only links get a token inertial (pybullet warns about each link without one)
    text = re.sub(r'<link name="([^"]+)"\s*/>',
                  lambda m: f'<link name="{m.group(1)}">{_TOKEN_INERTIAL}</link>', text)
    eyes = _EYE_XML.format(up=EYE_UP, fwd=EYE_FORWARD, half=EYE_HALF_BASELINE)
    return text.replace("</robot>", eyes + "</robot>")


def head_eye_urdf(robot_model: str = "iCubGazeboV2_5") -> str:
    """The URDF reduced to the links and joints between ``root_link`` and the two eyes."""
    root = ET.fromstring(icub_urdf_with_eyes(robot_model))
    joint_of = {j.find("child").get("link"): j for j in root.findall("joint")}
    links, joints = {"root_link"}, []
    for tip in ("l_eye", "r_eye"):
        link = tip
        while link != "root_link":
            joint = joint_of[link]
            if joint not in joints:
                joints.append(joint)
            links.add(link)
            link = joint.find("parent").get("link")
    out = ET.Element("robot", name=root.get("name", "iCub"))
    for link in root.findall("link"):
        if link.get("name") in links:
            out.append(link)
    for joint in reversed(joints):
        out.append(joint)
    return ET.tostring(out, encoding="unicode")


@lru_cache(maxsize=4)
def eye_chain(robot_model: str = "iCubGazeboV2_5"):
    """pytorch-kinematics chain (float64) root_link -> torso -> neck -> head -> both eyes.

    Joints (``chain.get_joint_parameter_names()``): torso_pitch, torso_roll, torso_yaw,
    neck_pitch, neck_roll, neck_yaw, eyes_tilt, l_eye_pan, r_eye_pan (tree order).
    """
    import pytorch_kinematics as pk

    chain = pk.build_chain_from_urdf(head_eye_urdf(robot_model).encode())
    return chain.to(dtype=torch.float64)


def _fk(chain, q: torch.Tensor, link: str) -> np.ndarray:
    """4x4 pose (numpy) of ``link`` in the root frame at joint values ``q``."""
    frames = chain.forward_kinematics(q.reshape(1, -1).to(torch.float64))
    return frames[link].get_matrix()[0].numpy()


class CameraScene:
    """A pybullet DIRECT world with the iCub, a screen and the eye camera.

    ``show`` puts stimuli in the screen's object slots (the pair layout's columns ``slot_xs``);
    ``render(tilt, pan)`` returns the 640x480 BGR image seen by the eye.
    """

    def __init__(self, cfg, pair_hw: tuple[int, int], slot_xs: tuple[float, ...], canvas: int):
        import pybullet as p

        self.p = p
        self.cfg = cfg
        self.pair_hw = pair_hw
        self.slot_xs = tuple(slot_xs)
        self.canvas = canvas
        self.client = p.connect(p.DIRECT)
        self._tmp = tempfile.TemporaryDirectory()
        try:
            self._build()
        except Exception:
            self.close()
            raise

    # ------------------------------------------------------------------ setup
    def _build(self) -> None:
        p, cfg, cid = self.p, self.cfg, self.client
        urdf_path = os.path.join(self._tmp.name, "icub_eyes.urdf")
        with open(urdf_path, "w", encoding="utf-8") as fh:
            fh.write(icub_urdf_with_eyes(cfg.robot_model))
        # merging the many fixed sensor/skin frames keeps pybullet's link state queries working
        with quiet_native_output():
            self.robot = p.loadURDF(urdf_path, useFixedBase=True,
                                    flags=p.URDF_MERGE_FIXED_LINKS, physicsClientId=cid)
        self.joint_index = {}
        for j in range(p.getNumJoints(self.robot, physicsClientId=cid)):
            info = p.getJointInfo(self.robot, j, physicsClientId=cid)
            self.joint_index[info[1].decode()] = j
        self.chain = eye_chain(cfg.robot_model)
        self.joint_names = self.chain.get_joint_parameter_names()
        self.eye_link = "l_eye" if cfg.eye == "left" else "r_eye"
        self.pan_joint = "l_eye_pan" if cfg.eye == "left" else "r_eye_pan"
        self.q0 = torch.zeros(len(self.joint_names), dtype=torch.float64)
        # the eye sits on the tilt and pan axes, so its position does not depend on them
        tf = _fk(self.chain, self.q0, self.eye_link)
        tf_other = _fk(self.chain, self.q0, "r_eye" if cfg.eye == "left" else "l_eye")
        self.eye_pos = tf[:3, 3]
        mid = 0.5 * (tf[:3, 3] + tf_other[:3, 3])
        self.forward = tf[:3, 2]  # head z at rest: the robot's forward direction
        self.up = tf[:3, 1]
        self.right = np.cross(self.forward, self.up)
        # screen plane: centred straight ahead of the eyes' midpoint; a grey panel with one
        # textured square per object slot, 1 mm in front of it
        h_px, w_px = self.pair_hw
        self.metres_per_px = cfg.object_width / self.canvas
        self.screen_centre = mid + cfg.screen_distance * self.forward
        self.panel = self._quad(self.screen_centre, w_px * self.metres_per_px,
                                h_px * self.metres_per_px)
        p.changeVisualShape(self.panel, -1, rgbaColor=[c / 255.0 for c in BACKGROUND_BGR[::-1]] + [1],
                            physicsClientId=cid)
        self.slots = {}
        for x in self.slot_xs:
            centre = self.screen_point(x) - 0.001 * self.forward
            self.slots[x] = self._quad(centre, cfg.object_width, cfg.object_width)
        self._textures: dict = {}
        self._blank = self._load_texture(
            np.full((TEXTURE_SCALE * self.canvas, TEXTURE_SCALE * self.canvas, 3),
                    BACKGROUND_BGR, np.uint8))
        for quad in self.slots.values():
            p.changeVisualShape(quad, -1, textureUniqueId=self._blank, rgbaColor=[1, 1, 1, 1],
                                physicsClientId=cid)
        f = 0.5 * cfg.image_height / np.tan(np.radians(cfg.fov_deg) / 2)
        self.focal_px = f
        self.projection = p.computeProjectionMatrixFOV(
            cfg.fov_deg, cfg.image_width / cfg.image_height, 0.02, 10.0, physicsClientId=cid)

    # ------------------------------------------------------------------ gaze
    def screen_point(self, x_px: float) -> np.ndarray:
        """World point of the pair image's pixel column ``x_px`` at mid-height."""
        w_px = self.pair_hw[1]
        return self.screen_centre + self.right * (x_px - (w_px - 1) / 2.0) * self.metres_per_px

    def gaze_angles(self, point: np.ndarray) -> tuple[float, float]:
        """Eye (tilt, pan) in radians that point the camera's optical axis at ``point``.

        With the eye on both axes, the optical axis after tilt t and pan p is
        ``(sin p, sin t cos p, cos t cos p)`` in the head frame (x left, y up, z forward).
        """
        tf_head = _fk(self.chain, self.q0, self.eye_link)  # eye frame at zero tilt/pan = head orientation
        d = tf_head[:3, :3].T @ (np.asarray(point) - self.eye_pos)
        d = d / np.linalg.norm(d)
        pan = float(np.arcsin(np.clip(d[0], -1, 1)))
        tilt = float(np.arctan2(d[1], d[2]))
        return tilt, pan

    def joint_vector(self, tilt: float, pan: float) -> torch.Tensor:
        q = self.q0.clone()
        q[self.joint_names.index("eyes_tilt")] = tilt
        q[self.joint_names.index(self.pan_joint)] = pan
        return q

    def camera_pose(self, q: torch.Tensor) -> np.ndarray:
        """4x4 pose of the eye camera (z = optical axis, y = image up) from FK."""
        return _fk(self.chain, q, self.eye_link)

    def set_joints(self, q: torch.Tensor) -> None:
        """Mirror the chain's joint values onto the pybullet robot (for its own link poses)."""
        for name, v in zip(self.joint_names, q.tolist()):
            self.p.resetJointState(self.robot, self.joint_index[name], v, physicsClientId=self.client)

    # ------------------------------------------------------------------ rendering
    def _quad(self, centre: np.ndarray, width: float, height: float) -> int:
        """A flat rectangle facing the robot; texture u along the robot's right, v upwards."""
        p, r, u = self.p, self.right, self.up
        verts = [centre - r * width / 2 - u * height / 2, centre + r * width / 2 - u * height / 2,
                 centre + r * width / 2 + u * height / 2, centre - r * width / 2 + u * height / 2]
        vs = p.createVisualShape(
            p.GEOM_MESH, vertices=[v.tolist() for v in verts], indices=[0, 1, 2, 0, 2, 3],
            uvs=[[0, 0], [1, 0], [1, 1], [0, 1]], normals=[(-self.forward).tolist()] * 4,
            physicsClientId=self.client)
        return p.createMultiBody(baseVisualShapeIndex=vs, physicsClientId=self.client)

    def _load_texture(self, image_bgr: np.ndarray) -> int:
        # a fresh file name each time: pybullet reuses a texture loaded from the same path
        self._n_loaded = getattr(self, "_n_loaded", 0) + 1
        path = os.path.join(self._tmp.name, f"texture{self._n_loaded}.png")
        cv2.imwrite(path, image_bgr)
        tex = self.p.loadTexture(path, physicsClientId=self.client)
        os.remove(path)
        return tex

    def texture(self, stimulus_set, item) -> int:
        """Texture of one stimulus (object, angle, appearance), loaded once per scene.

        pybullet's TinyRenderer ignores ``changeTexture``, so every distinct stimulus gets its own
        texture; a set's protocol has few (e.g. 36 for an Exp. 4 set).
        """
        key = (id(stimulus_set), stimulus_set.name, tuple(item))
        if key not in self._textures:
            obj, angle, app = item
            img = stimulus_set.image(obj, angle, app, canvas=TEXTURE_SCALE * self.canvas)
            self._textures[key] = self._load_texture(img)
        return self._textures[key]

    def show(self, stimulus_set, items: dict) -> None:
        """Show stimuli on the screen: ``items`` maps a slot x (pair-image column) to an
        (object, angle, appearance) or None (empty slot)."""
        for x, quad in self.slots.items():
            item = items.get(x)
            tex = self._blank if item is None else self.texture(stimulus_set, item)
            self.p.changeVisualShape(quad, -1, textureUniqueId=tex, physicsClientId=self.client)

    def render(self, tilt: float, pan: float) -> np.ndarray:
        """BGR uint8 image (height, width, 3) seen by the eye at (tilt, pan)."""
        p, cfg = self.p, self.cfg
        pose = self.camera_pose(self.joint_vector(tilt, pan))
        eye, fwd, up = pose[:3, 3], pose[:3, 2], pose[:3, 1]
        view = p.computeViewMatrix(eye.tolist(), (eye + fwd).tolist(), up.tolist(),
                                   physicsClientId=self.client)
        out = p.getCameraImage(
            cfg.image_width, cfg.image_height, view, self.projection,
            renderer=p.ER_TINY_RENDERER, shadow=0, lightAmbientCoeff=1.0,
            lightDiffuseCoeff=0.0, lightSpecularCoeff=0.0,
            flags=p.ER_NO_SEGMENTATION_MASK, physicsClientId=self.client)
        rgba = np.reshape(np.asarray(out[2], np.uint8), (cfg.image_height, cfg.image_width, 4))
        return np.ascontiguousarray(rgba[..., 2::-1])

    def window_px(self, point: np.ndarray) -> float:
        """Side in camera pixels of one object's square (``object_width``) seen at ``point``."""
        return float(self.focal_px * self.cfg.object_width / np.linalg.norm(point - self.eye_pos))

    def close(self) -> None:
        try:
            if self.p.isConnected(self.client):
                self.p.disconnect(self.client)
        finally:
            self._tmp.cleanup()
