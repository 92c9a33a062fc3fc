"""pytorch-kinematics FK of the iCub arm against pybullet's own link poses of the same URDF."""
import tempfile

import numpy as np
import pytest
import torch

from neuroimagery.robot.kinematics import ARM_JOINTS, ArmKinematics, icub_urdf_text
from neuroimagery.core.native import quiet_native_output as _quiet


@pytest.fixture(scope="module")
def kin():
    return ArmKinematics()


def test_joint_limits_come_from_the_urdf(kin):
    assert kin.joint_limits.shape == (7, 2)
    # r_elbow in the URDF: lower 0.2618, upper 1.8500
    assert kin.joint_limits[3].tolist() == pytest.approx([0.2617994, 1.8500490], abs=1e-6)
    assert (kin.joint_limits[:, 0] < kin.joint_limits[:, 1]).all()


def test_fk_matches_pybullet(kin):
    import pybullet as p

    text = icub_urdf_text(keep_geometry=False)
    with tempfile.NamedTemporaryFile("w", suffix=".urdf", delete=False) as f:
        f.write(text)
    with _quiet():
        cid = p.connect(p.DIRECT)
        body = p.loadURDF(f.name, useFixedBase=True, flags=p.URDF_MERGE_FIXED_LINKS, physicsClientId=cid)
    try:
        index = {p.getJointInfo(body, i, physicsClientId=cid)[1].decode(): i for i in range(p.getNumJoints(body, physicsClientId=cid))}
        chest = index["torso_yaw"]  # its child link is the chest
        hand = index["r_wrist_yaw"]  # its child link is r_hand
        gen = torch.Generator().manual_seed(0)
        lo, hi = kin.joint_limits[:, 0], kin.joint_limits[:, 1]
        qs = lo + (hi - lo) * torch.rand(50, 7, generator=gen)
        ours = kin.arm.forward_kinematics(qs).get_matrix()  # chest -> r_hand
        fast = kin.rake_pose_np(qs.numpy())  # world -> rake, float64 numpy chain
        chest_T_world = np.linalg.inv(kin.world_T_chest.double().numpy())
        hand_T_rake_inv = np.linalg.inv(kin.grasp.double().numpy())
        errs, rot_errs, fast_errs = [], [], []
        for q, T, F in zip(qs, ours, fast):
            for name, v in zip(ARM_JOINTS, q.tolist()):
                p.resetJointState(body, index[name], v, physicsClientId=cid)
            c = p.getLinkState(body, chest, computeForwardKinematics=True, physicsClientId=cid)
            h = p.getLinkState(body, hand, computeForwardKinematics=True, physicsClientId=cid)
            pos, orn = p.multiplyTransforms(*p.invertTransform(c[4], c[5]), h[4], h[5])
            R = np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3)
            errs.append(np.linalg.norm(np.array(pos) - T[:3, 3].numpy()))
            rot_errs.append(np.abs(R - T[:3, :3].numpy()).max())
            F_hand = chest_T_world @ F @ hand_T_rake_inv  # back to chest -> r_hand
            fast_errs.append(max(np.linalg.norm(np.array(pos) - F_hand[:3, 3]), np.abs(R - F_hand[:3, :3]).max()))
        # measured: max position error ~1e-7 m (float32 rounding), rotation ~1e-7
        assert max(errs) < 1e-5, max(errs)
        assert max(rot_errs) < 1e-5, max(rot_errs)
        assert max(fast_errs) < 1e-5, max(fast_errs)
    finally:
        p.disconnect(cid)


def test_batched_fk_equals_per_configuration_loop(kin):
    gen = torch.Generator().manual_seed(1)
    lo, hi = kin.joint_limits[:, 0], kin.joint_limits[:, 1]
    qs = lo + (hi - lo) * torch.rand(3, 4, 7, generator=gen)
    batched = kin.rake_head_position(qs)
    assert batched.shape == (3, 4, 3)
    loop = torch.stack([kin.rake_head_position(q) for q in qs.reshape(-1, 7)]).reshape(3, 4, 3)
    assert torch.allclose(batched, loop, atol=1e-6)


def test_limits_and_nan_are_rejected(kin):
    q = kin.joint_limits.mean(1)
    kin.check_limits(q)
    bad = q.clone()
    bad[3] = 3.0
    with pytest.raises(ValueError, match="r_elbow"):
        kin.check_limits(bad)
    bad[3] = float("nan")
    with pytest.raises(ValueError, match="NaN"):
        kin.check_limits(bad)
