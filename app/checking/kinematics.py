"""Forward kinematics in numpy, many configurations at once, for a tree of revolute, prismatic and weld joints.

A Drake context answers one configuration at a time through Python. Rejection sampling of workspace placements asks
where a robot piece is for some hundred configurations per sample it keeps, and the certificate wants every robot
geometry's pose at each configuration it bounds: here a batch of them costs a fraction of Drake's time per
configuration (benchmark pages, "Tuning notes"). The joints' fixed frames are read from the plant once; a plant with
a joint of any other kind (a floating base's quaternion) has no TreeKinematics and its callers ask Drake.
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
        # Per body: (parent slot, its row among the moving bodies or None, a weld's constant (R_PC, p_PC)); the
        # world: None. X_PC = X_PF X_FM(q) X_MC is written so that q enters only through scalars: a revolute joint
        # turning by q about the unit axis k (K = [k]x) gives R_FM = I + sin q K + (1 - cos q) K^2 (Rodrigues), so
        # R_PC = A0 + sin q A1 + (1 - cos q) A2 and p_PC = b0 + sin q b1 + (1 - cos q) b2; a prismatic one,
        # R_PC = A0 and p_PC = b0 + q b1. So a moving body's X_PC, as 12 numbers (R_PC row-major, then p_PC), is
        # [1, sin q, 1 - cos q] or [1, q, 0] times a (3, 12) table of constants: all moving bodies' in one product.
        self._bodies, tables, columns, multipliers, offsets, revolute = [], [], [], [], [], []
        for joint, parent in order:
            if joint is None:
                self._bodies.append(None)
                continue
            X_PF = joint.frame_on_parent().GetFixedPoseInBodyFrame()
            X_MC = joint.frame_on_child().GetFixedPoseInBodyFrame().inverse()
            kind = joint.type_name()
            if kind == "weld":
                X = X_PF.multiply(joint.X_FM()).multiply(X_MC)
                self._bodies.append((parent, None, (X.rotation().matrix(), X.translation())))
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
            self._bodies.append((parent, len(tables), None))
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

    def _chain(self, Q: np.ndarray) -> tuple[list, list]:
        """Every body's world rotation and position, in `_bodies` order: (n, 3, 3) and (n, 3), or (3, 3) and (3,)
        for a body welded to the world (directly or through other welds: a cart, a mounting plate), which every
        configuration shares, so that it is computed once and its children multiply by one matrix."""
        x = Q[:, self._columns] * self._multipliers + self._offsets
        coefficients = np.stack(
            [np.ones_like(x), np.where(self._revolute, np.sin(x), x), np.where(self._revolute, 1.0 - np.cos(x), 0.0)],
            axis=2,
        )
        local = np.einsum("nbk,bkm->bnm", coefficients, self._tables)  # (moving bodies, n, 12)
        R, p = [], []
        for body in self._bodies:
            if body is None:  # the world
                R.append(np.eye(3))
                p.append(np.zeros(3))
                continue
            parent, moving, constants = body
            if moving is None:
                R_PC, p_PC = constants
            else:
                R_PC, p_PC = local[moving, :, :9].reshape(-1, 3, 3), local[moving, :, 9:]
            R.append(R[parent] @ R_PC)
            p.append(p[parent] + _apply(R[parent], p_PC))
        return R, p

    def _body_poses(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Every body's world rotation (n, bodies, 3, 3) and position (n, bodies, 3)."""
        R, p = self._chain(Q)
        rotations, positions = np.empty((len(Q), len(R), 3, 3)), np.empty((len(Q), len(R), 3))
        for j, (r, x) in enumerate(zip(R, p)):
            rotations[:, j], positions[:, j] = r, x
        return rotations, positions

    def poses(self, Q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each frame's world rotation (n, frames, 3, 3) and origin (n, frames, 3)."""
        R, p = self._body_poses(np.atleast_2d(np.asarray(Q, float)))
        R_B, p_B = R[:, self._frame_body], p[:, self._frame_body]
        return R_B @ self._frame_R, p_B + _apply(R_B, self._frame_p)

    def frame_origins(self, Q: np.ndarray) -> np.ndarray:
        """Each frame's world origin (n, frames, 3): the second half of `poses`, the same numbers, without the
        frames' rotations and the copies of every body's pose, which cost half of it."""
        Q = np.atleast_2d(np.asarray(Q, float))
        R, p = self._chain(Q)
        out = np.empty((len(Q), len(self._frame_body), 3))
        for j in np.unique(self._frame_body).tolist():  # by body: its frames at once, its pose not copied out
            frames = np.flatnonzero(self._frame_body == j)
            R_j = np.broadcast_to(R[j], (len(Q), 3, 3)) if R[j].ndim == 2 else R[j]
            p_j = np.broadcast_to(p[j], (len(Q), 3)) if p[j].ndim == 1 else p[j]
            out[:, frames] = p_j[:, None, :] + _apply(R_j[:, None], self._frame_p[frames])
        return out

    def origins(self, Q: np.ndarray, frames: np.ndarray) -> np.ndarray:
        """The world origin of frame frames[i] in configuration Q[i], (n, 3)."""
        R, p = self._chain(np.atleast_2d(np.asarray(Q, float)))
        body = self._frame_body[frames]
        out = np.empty((len(frames), 3))
        for j in np.unique(body).tolist():  # by body: the rows of the frames on it
            rows = np.flatnonzero(body == j)
            R_j = R[j] if R[j].ndim == 2 else R[j][rows]
            p_j = p[j] if p[j].ndim == 1 else p[j][rows]
            out[rows] = p_j + _apply(R_j, self._frame_p[frames[rows]])
        return out


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


def _apply(R: np.ndarray, v: np.ndarray) -> np.ndarray:
    """R @ v for broadcast stacks of rotations (..., 3, 3) and vectors (..., 3). Written out by column: numpy's
    stacked 3 x 3 products cost several times their arithmetic, and one rotation for all is one matrix product."""
    if R.ndim == 2:
        return v @ R.T
    return R[..., 0] * v[..., 0, None] + R[..., 1] * v[..., 1, None] + R[..., 2] * v[..., 2, None]
