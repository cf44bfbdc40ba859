"""Forward kinematics, many configurations at once, for a tree of revolute, prismatic and weld joints.

A Drake context answers one configuration at a time through Python. Rejection sampling of workspace placements asks
where a robot piece is for some hundred configurations per sample it keeps, and the certificate wants every robot
geometry's pose at each configuration it bounds: here a batch of them costs a fraction of Drake's time per
configuration (benchmark pages, "Tuning notes"). The joints' fixed frames are read from the plant once; a plant with
a joint of any other kind (a floating base's quaternion) has no TreeKinematics and its callers ask Drake. The
products along the chain are compiled (app.checking.kernels), in the order written, so that the poses do not depend
on which BLAS kernel a machine's numpy picks for small matrices.
"""

from __future__ import annotations

import numpy as np

_KINDS = ("revolute", "prismatic", "weld")


class TreeKinematics:
    """World poses of fixed frames on a plant's bodies (each given as (body, X_BF)), for configurations (n, dim):
    the plant's positions, or with a `position_map` (app.scene.cspace.PositionMap) the coordinates it maps to them,
    each mimic joint's position being its multiplier times its coordinate plus its offset, a held joint's its own."""

    def __init__(self, plant, frames: list, position_map=None):
        inboard = {}
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            inboard[joint.child_body().index()] = joint
        # The bodies the frames hang on and every body inboard of them, parents before children.
        order, slot = [], {}

        def add(body_index) -> int:
            if body_index not in slot:
                joint = inboard.get(body_index)
                parent = add(joint.parent_body().index()) if joint is not None else None
                slot[body_index] = len(order)
                order.append((joint, parent))
            return slot[body_index]

        self._frame_body = np.array([add(body.index()) for body, _ in frames], int)
        self._frame_R = np.array([X.rotation().matrix() for _, X in frames]).reshape(-1, 3, 3)
        self._frame_p = np.array([X.translation() for _, X in frames]).reshape(-1, 3)
        # Per body (kernels.body_poses): its parent's slot (-1: the world), its row among the moving bodies (-1: the
        # world or a weld), and a weld's constant pose in its parent (R_PC, p_PC; zeros otherwise). X_PC = X_PF
        # X_FM(q) X_MC is written so that q enters only through scalars: a revolute joint turning by q about the
        # unit axis k (K = [k]x) gives R_FM = I + sin q K + (1 - cos q) K^2 (Rodrigues), so R_PC = A0 + sin q A1 +
        # (1 - cos q) A2 and p_PC = b0 + sin q b1 + (1 - cos q) b2; a prismatic one, R_PC = A0 and p_PC = b0 + q b1.
        # So a moving body's X_PC, as 12 numbers (R_PC row-major, then p_PC), is [1, sin q, 1 - cos q] or [1, q, 0]
        # times a (3, 12) table of constants.
        self._parent = np.full(len(order), -1, np.int64)
        self._moving = np.full(len(order), -1, np.int64)
        self._welded_R, self._welded_p = np.zeros((len(order), 3, 3)), np.zeros((len(order), 3))
        tables, columns, multipliers, offsets, revolute = [], [], [], [], []
        for body, (joint, parent) in enumerate(order):
            if joint is None:  # the world
                continue
            self._parent[body] = parent
            X_PF = joint.frame_on_parent().GetFixedPoseInBodyFrame()
            X_MC = joint.frame_on_child().GetFixedPoseInBodyFrame().inverse()
            kind = joint.type_name()
            if kind == "weld":
                X = X_PF.multiply(joint.X_FM()).multiply(X_MC)
                self._welded_R[body], self._welded_p[body] = X.rotation().matrix(), X.translation()
                continue
            R_PF, p_PF, R_MC, p_MC = (
                X_PF.rotation().matrix(),
                X_PF.translation(),
                X_MC.rotation().matrix(),
                X_MC.translation(),
            )
            table = np.zeros((3, 12))
            table[0] = np.concatenate([(R_PF @ R_MC).ravel(), p_PF + R_PF @ p_MC])
            if kind == "revolute":
                k = joint.revolute_axis()
                K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
                table[1] = np.concatenate([(R_PF @ K @ R_MC).ravel(), R_PF @ K @ p_MC])
                table[2] = np.concatenate([(R_PF @ K @ K @ R_MC).ravel(), R_PF @ K @ K @ p_MC])
            else:
                table[1, 9:] = R_PF @ joint.translation_axis()
            column, multiplier, offset = _coordinate(joint, position_map)
            self._moving[body] = len(tables)
            tables.append(table)
            columns.append(column)
            multipliers.append(1.0 if multiplier is None else multiplier)
            offsets.append(0.0 if offset is None else offset)
            revolute.append(kind == "revolute")
        self._tables = np.array(tables).reshape(-1, 3, 12)
        self._columns = np.array(columns, int)
        self._multipliers, self._offsets = np.array(multipliers), np.array(offsets)
        self._revolute = np.array(revolute, bool)

    @classmethod
    def of(cls, plant, frames: list, position_map=None) -> TreeKinematics | None:
        """TreeKinematics of `frames`, or None if the plant has a joint that is not revolute, prismatic or weld."""
        kinds = {plant.get_joint(i).type_name() for i in plant.GetJointIndices()}
        return cls(plant, frames, position_map) if kinds <= set(_KINDS) else None

    def _body_poses(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every body's world rotation (n, bodies, 3, 3) and position (n, bodies, 3), parents before children. X_PC of a
        moving body is [1, sin q, 1 - cos q] (revolute) or [1, q, 0] (prismatic) times its table (see __init__);
        the sines and cosines are numpy's, the products compiled (kernels.body_poses)."""
        from app.checking import kernels  # loads numba on first use (see there)

        Q = np.atleast_2d(np.asarray(Q, float))
        x = Q[:, self._columns] * self._multipliers + self._offsets
        turn = np.ascontiguousarray(np.where(self._revolute, np.sin(x), x))
        bend = np.ascontiguousarray(np.where(self._revolute, 1.0 - np.cos(x), 0.0))
        return kernels.body_poses(turn, bend, self._tables, self._parent, self._moving, self._welded_R, self._welded_p)

    def poses(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each frame's world rotation (n, frames, 3, 3) and origin (n, frames, 3)."""
        from app.checking import kernels

        R, p = self._body_poses(Q)
        return kernels.frame_poses(R, p, self._frame_body, self._frame_R, self._frame_p)

    def frame_origins(self, Q: np.ndarray) -> np.ndarray:
        """Each frame's world origin (n, frames, 3): the second half of `poses`."""
        return self.poses(Q)[1]

    def origins(self, Q: np.ndarray, frames: np.ndarray) -> np.ndarray:
        """The world origin of frame frames[i] in configuration Q[i], (n, 3)."""
        from app.checking import kernels

        R, p = self._body_poses(Q)
        frames = np.asarray(frames, np.int64)
        return kernels.frame_origins_at(R, p, self._frame_body[frames], self._frame_p[frames])


def _coordinate(joint, position_map) -> tuple:
    """(column of the configuration, multiplier, offset) giving a joint's position: (its position index, None, None)
    without a map; a weld has none."""
    if joint.type_name() == "weld":
        return (-1, None, None)
    start = joint.position_start()
    if position_map is None:
        return (start, None, None)
    for position, column, multiplier, offset in position_map.mimics:
        if position == start:
            return (column, multiplier, offset)
    held = position_map.held.get(position_map.names[start])
    if held is not None:  # a held joint: any column, times nothing, plus its position
        return (0, 0.0, held)
    return (int(np.flatnonzero(position_map.planned == start)[0]), None, None)
