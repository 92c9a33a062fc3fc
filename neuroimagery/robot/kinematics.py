"""Forward kinematics of the iCub's right arm, head and the rake it holds.

The body comes from the real iCub URDF shipped by the ``icub-models`` package
(``iCubGazeboV2_5``).  A pytorch-kinematics serial chain ``chest -> r_hand`` gives the pose of the
hand for whole batches of joint vectors; the torso is held at zero, so the constant transform
``root_link -> chest`` is computed once.

Frames
------
*URDF root frame* (``root_link``, the waist): x points backward, y to the robot's right, z up.
*World frame* (used by the pybullet scene and everything in :mod:`neuroimagery.robot.world`):
x points forward (away from the robot, "north"), y to the robot's left ("west"), z up; its origin
is below the waist, on the floor.  ``world_T_root`` is a half turn about z plus a lift of
``root_height``.

The rake is rigidly attached to the hand (a fixed grasp); its head centre sits at a fixed offset in
the hand frame, so ``rake_head_position(q)`` is one matrix product after FK.
"""
from __future__ import annotations

import copy
import functools
import re
from pathlib import Path

import numpy as np
import torch

from ..nn.functional import checks_enabled

ARM_JOINTS = (
    "r_shoulder_pitch",
    "r_shoulder_roll",
    "r_shoulder_yaw",
    "r_elbow",
    "r_wrist_prosup",
    "r_wrist_pitch",
    "r_wrist_yaw",
)
HEAD_JOINTS = ("neck_pitch", "neck_roll", "neck_yaw")
ICUB_MODEL = "iCubGazeboV2_5"


@functools.lru_cache(maxsize=4)
def icub_urdf_path(model: str = ICUB_MODEL) -> Path:
    """Path of the icub-models URDF file of ``model``."""
    import icub_models

    return Path(icub_models.get_model_file(model))


@functools.lru_cache(maxsize=4)
def icub_urdf_text(model: str = ICUB_MODEL, keep_geometry: bool = True) -> str:
    """URDF text with the Gazebo-only ``<sensor>``/``<gazebo>`` blocks removed.

    Those blocks are ignored by both pytorch-kinematics and pybullet but make the former print
    one warning per tag.  With ``keep_geometry=False`` the visual and collision elements are
    dropped too (enough for kinematics, and loads in pybullet without meshes).
    """
    text = icub_urdf_path(model).read_text()
    text = re.sub(r"<sensor\b.*?</sensor>", "", text, flags=re.S)
    text = re.sub(r"<gazebo\b.*?</gazebo>", "", text, flags=re.S)
    if not keep_geometry:
        text = re.sub(r"<visual\b.*?</visual>", "", text, flags=re.S)
        text = re.sub(r"<collision\b.*?</collision>", "", text, flags=re.S)
    else:
        import icub_models

        share = Path(icub_models.get_models_path()).parent  # .../share/iCub
        text = text.replace("package://iCub/", f"{share}/")
    return text


@functools.lru_cache(maxsize=2)
def _chains(default_dtype: torch.dtype) -> tuple:
    """The pytorch-kinematics chains ``chest -> r_hand``, ``chest -> head`` and ``root_link -> chest``
    of the URDF, parsed once per process (at the default dtype they are built in); every
    :class:`ArmKinematics` takes copies of its own (``Chain.to`` changes a chain in place)."""
    import pytorch_kinematics as pk

    text = icub_urdf_text(ICUB_MODEL, keep_geometry=False)
    return tuple(pk.build_serial_chain_from_urdf(text, end_link_name=end, root_link_name=root)
                 for end, root in (("r_hand", "chest"), ("head", "chest"), ("chest", "root_link")))


def world_T_root(root_height: float) -> torch.Tensor:
    """World pose of the URDF root frame (a half turn about z, lifted by ``root_height``)."""
    return _world_T_root(root_height)


def _world_T_root(root_height: float) -> torch.Tensor:
    T = torch.eye(4)
    T[0, 0] = -1.0
    T[1, 1] = -1.0
    T[2, 3] = root_height
    return T


class ArmKinematics(torch.nn.Module):
    """Batched FK of the right arm (7 joints) and of the head (3 neck joints).

    Parameters
    ----------
    root_height: height of the iCub's waist (``root_link``) above the floor, metres.
    grasp: 4x4 transform from the hand frame (``r_hand``) to the rake frame (the rake's handle
        end in the palm; the rake's +x runs along the handle).
    rake_head_offset: position of the rake head's centre in the rake frame, metres.
    eye_offset: position of the right eye in the ``head`` link frame, metres (the icub-models
        URDF has no eye joints; the eyes are held still at this point).

    Buffers ``joint_limits`` (7, 2) hold the URDF's lower/upper limits in radians. The
    pytorch-kinematics chains (``arm``, ``head``) follow the module's device and dtype
    (``.to()``, ``.double()``, ``.cuda()``), so FK runs in the dtype of ``joint_limits``.
    """

    def __init__(
        self,
        root_height: float = 0.80,
        grasp: torch.Tensor | None = None,
        rake_head_offset: tuple[float, float, float] = (0.30, 0.0, 0.0),
        eye_offset: tuple[float, float, float] = (0.034, 0.11, 0.06),
        dtype: torch.dtype = torch.float32,
    ) -> None:
        super().__init__()
        self.arm, self.head, torso = (copy.deepcopy(c).to(dtype=dtype) for c in _chains(torch.get_default_dtype()))
        if tuple(self.arm.get_joint_parameter_names()) != ARM_JOINTS:
            raise RuntimeError(f"unexpected arm joints {self.arm.get_joint_parameter_names()}")
        self._arm_end, self._head_end = _end_frame(self.arm, "r_hand", 7), _end_frame(self.head, "head", 3)
        root_T_chest = torso.forward_kinematics(torch.zeros(1, 3, dtype=dtype)).get_matrix()[0]
        lo, hi = self.arm.get_joint_limits()
        self.register_buffer("joint_limits", torch.tensor([lo, hi], dtype=dtype).T.contiguous())
        self.register_buffer("world_T_chest", _world_T_root(root_height).to(dtype) @ root_T_chest)
        if grasp is None:
            grasp = default_grasp()
        self.register_buffer("grasp", grasp.to(dtype))
        self.register_buffer("rake_head_offset", torch.tensor([*rake_head_offset, 1.0], dtype=dtype))
        self.register_buffer("eye_offset", torch.tensor([*eye_offset, 1.0], dtype=dtype))
        self.root_height = root_height

    def _apply(self, fn, recurse=True):
        """Move and cast the chains with the buffers (they are not modules, so ``nn.Module`` would not)."""
        out = super()._apply(fn, recurse)
        like = self.joint_limits
        self.arm = self.arm.to(dtype=like.dtype, device=like.device)
        self.head = self.head.to(dtype=like.dtype, device=like.device)
        return out

    # ------------------------------------------------------------------ arm
    def check_limits(self, q: torch.Tensor, tol: float = 1e-6) -> None:
        """Raise ``ValueError`` if any joint value in ``q`` (..., 7) is outside the URDF limits or NaN."""
        if q.shape[-1] != 7:
            raise ValueError(f"joint vectors must have 7 entries (right arm), got shape {tuple(q.shape)}")
        if not checks_enabled(q):  # the checks read values (meta device, torch.compile, checks(False))
            return
        if not torch.isfinite(q).all():
            raise ValueError("joint trajectory contains NaN or inf")
        lo, hi = self.joint_limits[:, 0], self.joint_limits[:, 1]
        below = q < lo - tol
        above = q > hi + tol
        if below.any() or above.any():
            bad = (below | above).reshape(-1, 7).any(0).nonzero().flatten().tolist()
            names = ", ".join(
                f"{ARM_JOINTS[j]} in [{lo[j]:.3f}, {hi[j]:.3f}] rad (got {q[..., j].min():.3f}..{q[..., j].max():.3f})"
                for j in bad
            )
            raise ValueError(f"joint target outside the URDF limits: {names}")

    def clamp(self, q: torch.Tensor) -> torch.Tensor:
        """Clip joint values to the URDF limits."""
        return torch.maximum(torch.minimum(q, self.joint_limits[:, 1]), self.joint_limits[:, 0])

    def forward(self, q: torch.Tensor) -> torch.Tensor:
        """World pose (..., 4, 4) of the hand frame ``r_hand`` for joint vectors ``q`` (..., 7)."""
        shape = q.shape[:-1]
        flat = q.reshape(-1, 7).to(self.joint_limits.dtype)
        # the hand's frame of all the chain's transforms: forward_kinematics(flat).get_matrix() without its
        # host look-up of the frame index (so FK also runs on meta)
        chest_T_hand = self.arm.forward_kinematics_tensor(flat)[self._arm_end]
        return (self.world_T_chest @ chest_T_hand).reshape(*shape, 4, 4)

    def rake_pose_np(self, q: np.ndarray) -> np.ndarray:
        """Float64 numpy FK of the rake frame for ``q`` (..., 7): the same chain as :meth:`rake_pose`.

        A plain product of the chain's fixed transforms and Rodrigues rotations, several times
        cheaper than the general tree FK for the rollouts' large batches.
        """
        return self.rake_frames_np(q)[0]

    def rake_frames_np(self, q: np.ndarray, joints: bool = False):
        """:meth:`rake_pose_np`'s FK -> the rake poses (..., 4, 4) and, with ``joints``, each arm
        joint's world axis (..., 7, 3) and a point on it (..., 7, 3), in joint order: the
        columns of the point Jacobian (``axis x (p - point)``)."""
        if getattr(self, "_np_chain", None) is None:
            a = self.arm
            offsets = a._static_offsets.detach().double().cpu().numpy()
            kinds = a.joint_type_indices.cpu().numpy()
            jidx = a._joint_indices_clamped.cpu().numpy()
            axes = a.axes.detach().double().cpu().numpy()
            order = [int(f) for level in a._bfs_levels for f in level.flatten().tolist()]
            parents = a._direct_parent_idx.cpu().numpy()
            if any(int(parents[f]) != (order[i - 1] if i else -1) for i, f in enumerate(order)):
                raise RuntimeError("the arm chain is not serial")
            chain = [(offsets[f], int(jidx[f]) if kinds[f] == 1 else None) for f in order]
            if any(kinds[f] not in (0, 1) for f in order):
                raise RuntimeError("the arm chain has a joint that is neither fixed nor revolute")
            self._np_chain = (chain, axes, self.world_T_chest.double().cpu().numpy(), self.grasp.double().cpu().numpy())
        chain, axes, world_T_chest, grasp = self._np_chain
        q = np.asarray(q, dtype=np.float64)
        shape = q.shape[:-1]
        q = q.reshape(-1, 7)
        T = np.broadcast_to(world_T_chest, (len(q), 4, 4)).copy()
        axis_w = np.zeros((len(q), 7, 3)) if joints else None
        point_w = np.zeros((len(q), 7, 3)) if joints else None
        for offset, j in chain:
            T = T @ offset
            if j is not None:
                k = axes[j]
                if joints:
                    axis_w[:, j] = T[:, :3, :3] @ k
                    point_w[:, j] = T[:, :3, 3]
                K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
                s, c = np.sin(q[:, j])[:, None, None], np.cos(q[:, j])[:, None, None]
                R = np.eye(3) + s * K + (1 - c) * (K @ K)
                T[:, :, :3] = T[:, :, :3] @ R
        pose = (T @ grasp).reshape(*shape, 4, 4)
        if not joints:
            return pose, None, None
        return pose, axis_w.reshape(*shape, 7, 3), point_w.reshape(*shape, 7, 3)

    def rake_pose(self, q: torch.Tensor) -> torch.Tensor:
        """World pose (..., 4, 4) of the rake frame (hand pose times the fixed grasp)."""
        return self.forward(q) @ self.grasp

    def rake_head_position(self, q: torch.Tensor) -> torch.Tensor:
        """World position (..., 3) of the rake head's centre."""
        return (self.rake_pose(q) @ self.rake_head_offset)[..., :3]

    # ----------------------------------------------------------------- head
    def eye_pose(self, neck: torch.Tensor | None = None) -> torch.Tensor:
        """World pose (4, 4) of the right eye: FK of the neck chain plus the fixed eye offset.

        The camera looks along the head frame's +z axis... of the world: see :meth:`eye_look`.
        """
        if neck is None:
            neck = self.joint_limits.new_zeros(3)
        T = self.world_T_chest @ self.head.forward_kinematics_tensor(neck.reshape(1, 3))[self._head_end][0]
        T = T.clone()
        T[:, 3] = T @ self.eye_offset
        return T


def _end_frame(chain, link: str, n_joints: int) -> int:
    """Index of ``link``'s frame among the transforms of ``chain.forward_kinematics_tensor``, which
    takes the chain's own joints in order (so FK needs no host look-ups: it runs on ``meta`` too)."""
    if chain.n_joints != n_joints or chain._serial_frames[-1].name != link:
        raise RuntimeError(f"unexpected chain to {link!r}: {chain.n_joints} joints, "
                           f"ends in {chain._serial_frames[-1].name!r}")
    return int(chain.get_frame_indices(link)[0])


def default_grasp() -> torch.Tensor:
    """Fixed hand->rake transform: the handle leaves the palm along the hand frame's -y axis.

    Chosen by looking at the hand frame of ``r_hand`` in the URDF: with the arm stretched
    forward its -y axis points away from the palm, down through the fingers' side.
    """
    T = torch.eye(4)
    # rake +x (along the handle) = hand -y ; rake +z = hand +x ; rake +y = rake z cross rake x
    T[:3, 0] = torch.tensor([0.0, -1.0, 0.0])
    T[:3, 2] = torch.tensor([1.0, 0.0, 0.0])
    T[:3, 1] = torch.linalg.cross(T[:3, 2], T[:3, 0])
    return T
