"""Section 2.1: the robot as a graph.

The graph's vertices are the massive bodies B_1..B_n and the ground B_0; its edges are the
joints O_j, each the inner joint of exactly one body (a tree). A massless carriage and the joint
that carries it (kr500's rail) belong to the moving base: O_1 then connects B_1 to that base,
which plays the part of B_0. A chain of hinges through massless carriages at one point between two
bodies (a ball joint read as its three hinges, harness/model/mjcf.py; a universal joint) is one edge,
from the body's nearest massive ancestor: a carriage transmits the wrench it carries unchanged, and
each hinge of the chain drives the component of the edge's moment along its own axis. The force
elements of the paper are the joint force elements, one per joint, so the force-element matrices
equal the joint matrices (S_e = S, C_e = C).

Conventions (signs restored where the text extraction lost them, and fixed by Eqs. 25-27):
- S_ij = +1 if O_j starts at B_i (B_i is its inner body), -1 if O_j ends at B_i (B_i is its outer
  body), 0 otherwise (Eqs. 5-6).
- c_ij: the vector from O_ci to joint point O_j; C_ij = S_ij c_ij (Eqs. 9-10). For kr500 every
  non-zero C_ij is +(l_i / 2) e1(i), as printed. The joint point is the point of the outer body
  where the force element acts; across a prismatic joint it slides along the axis relative to the
  inner body, so there c_ij = c_ij(0) + q_j u_j^(i) for the inner body (the paper's robot has
  revolute joints only, where c_ij is constant).
- With F_k the force and M_k the moment (about O_k) that the inner body applies to the outer body
  across O_k, the resultants on B_i are
      F_i^J = -sum_k S_e,ik F_k                       (Eq. 17, force elements on B_i)
      M_i^J = -sum_k (C_e,ik x F_k + S_ik M_k)        (Eqs. 20, 26, about O_ci)
  and the Newton-Euler equations read m_i r_i'' = m_i g + F_i^J and
  J_i omega_i' + omega_i x J_i omega_i = M_i^J (Eqs. 22-23).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from harness.model.kinematics import cross, rotate
from harness.model.spec import RobotSpec


@dataclass(frozen=True, eq=False)
class Topology:
    bodies: tuple[str, ...]  # B_1..B_n, massive bodies in tree order
    joints: tuple[str, ...]  # O_1..O_n, O_j the inner joint of B_j
    S: np.ndarray  # (n, n) incidence matrix, Eqs. 5-6
    c_B: np.ndarray  # (n, n, 3) c_ij at the initial pose, body-i components, zero where S_ij = 0
    slide_B: np.ndarray  # (n, n, 3) u_j^(i) for B_i the inner body of a prismatic O_j, else zero

    @property
    def S_e(self) -> np.ndarray:
        """Eqs. 14-16: path matrix of the force elements (the joint force elements)."""
        return self.S

    def C_B(self) -> np.ndarray:
        """Eqs. 9-10 (and Eq. 19, C_e = C): weighted body-joint vectors C_ij = S_ij c_ij at the
        initial pose, body-i components. `joint_arms` gives them in the world, sliding ones included."""
        return self.S[..., None] * self.c_B

    @property
    def n(self) -> int:
        return len(self.bodies)

    @functools.cached_property
    def S_inv(self) -> np.ndarray:
        """S^-1, made once: S of a tree in root-first order is upper triangular with -1 on its
        diagonal, so S^-1 sums each joint's wrench from the outermost body in (Eq. 23 solved for the
        joint moments)."""
        return np.linalg.inv(self.S.astype(float))

    @property
    def S_e_inv(self) -> np.ndarray:
        """S_e^-1 (Eq. 22 solved for the force elements)."""
        return self.S_inv

    @functools.cached_property
    def outer(self) -> np.ndarray:
        """(n,) each joint O_k's outer body i (S_ik = -1)."""
        return np.argmax(self.S == -1, axis=0)

    @functools.cached_property
    def inner(self) -> np.ndarray:
        """(n,) each joint O_k's inner body i (S_ik = +1), -1 where it is the ground."""
        return np.where(np.any(self.S == 1, axis=0), np.argmax(self.S == 1, axis=0), -1)

    @functools.cached_property
    def outer_of(self) -> np.ndarray:
        """(n, n) 1 where B_i is O_k's outer body (S_ik = -1)."""
        return (self.S == -1).astype(float)

    @functools.cached_property
    def inner_of(self) -> np.ndarray:
        """(n, n) 1 where B_i is O_k's inner body (S_ik = +1)."""
        return (self.S == 1).astype(float)


def build_topology(spec: RobotSpec) -> Topology:
    """S and c for any tree of the spec; nothing here is specific to six bodies. Each edge joins a body to
    its nearest massive ancestor or the ground, through the massless carriages between them (the module
    docstring)."""
    bodies = tuple(b.name for b in spec.massive_bodies)
    joints = tuple(spec.inner_joint(b).name for b in bodies)
    index = {b: i for i, b in enumerate(bodies)}
    n = len(bodies)
    S = np.zeros((n, n), dtype=int)
    c_B = np.zeros((n, n, 3))
    slide_B = np.zeros((n, n, 3))
    for k, name in enumerate(joints):
        joint = spec.joint(name)
        ends = [(index[joint.child], -1)]
        parent = spec.massive_parent(joint.child)[0]
        if parent in index:
            ends.append((index[parent], +1))
        for i, sign in ends:
            body = spec.body(bodies[i])
            S[i, k] = sign
            c_B[i, k] = body.arm_B(joint.p_W0)
            if sign > 0 and not joint.revolute:
                slide_B[i, k] = body.R_WB0.T @ joint.axis_W0
    return Topology(bodies, joints, S, c_B, slide_B)


def joint_arms(top: Topology, A: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World vectors from each joint's outer and inner body's centre of mass to the joint point,
    (N, n_joints, 3) each; the inner one is zero where the inner body is the ground. These are
    the non-zero C_e,ik of Eq. 19 (with signs S_ik), gathered joint by joint."""
    c_out, c_in = joint_arms_components(top, np.asarray(A).transpose(2, 3, 1, 0), np.asarray(q).T)
    return c_out.transpose(2, 1, 0), c_in.transpose(2, 1, 0)


def joint_arms_components(top: Topology, A: np.ndarray, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """joint_arms component-major with the samples last: A (3, 3, n, N) with A[i, j] the (n, N)
    entries A_ij, q (n, N); the arms (3, n_joints, N) each."""
    k, outer, inner = np.arange(top.n), top.outer, top.inner
    A_out = A if np.array_equal(outer, k) else A[:, :, outer]
    c_out = rotate(A_out, top.c_B[outer, k].T[:, :, None])
    c_in = np.zeros_like(c_out)
    for j in np.flatnonzero(inner >= 0):  # joint by joint: no copy of the inner bodies' rotations
        arm_B = top.c_B[inner[j], j][:, None] + top.slide_B[inner[j], j][:, None] * q[j]
        c_in[:, j] = np.einsum("ijn,jn->in", A[:, :, inner[j]], arm_B)
    return c_out, c_in


def joint_resultants(top: Topology, A: np.ndarray, q: np.ndarray, F_W: np.ndarray, M_W: np.ndarray):
    """Resultant force and moment (about each centre of mass) of the joints on every body.

    A: (N, n, 3, 3) A(0i) per sample and body; q: (N, n) joint coordinates of O_1..O_n;
    F_W, M_W: (N, n, 3) force and moment (about the joint point) of the inner on the outer body
    across each joint, world components.
    Returns F_J_W, M_J_W, each (N, n, 3), world components (Eqs. 17, 20, 26), and the sizes of the
    terms summed into each, (N, n) each: the scale at which they cancel."""
    c_out, c_in = joint_arms(top, A, q)
    P_out, P_in = top.outer_of, top.inner_of
    on_outer = M_W + cross(c_out, F_W)  # -(C_e x F + S M) for S = -1
    on_inner = M_W + cross(c_in, F_W)
    F_J_W = -(top.S_e.astype(float) @ F_W)
    M_J_W = P_out @ on_outer - P_in @ on_inner
    F_norm = np.linalg.norm(F_W, axis=-1)
    F_size = np.einsum("ik,nk->ni", P_out + P_in, F_norm)
    # a moment about the centre of mass is M + c x F: both terms count, since they may cancel (the
    # outermost body of an arm at rest carries no moment about its centre of mass at all)
    M_norm = np.linalg.norm(M_W, axis=-1)
    M_size = (np.einsum("ik,nk->ni", P_out, M_norm + np.linalg.norm(cross(c_out, F_W), axis=-1))
              + np.einsum("ik,nk->ni", P_in, M_norm + np.linalg.norm(cross(c_in, F_W), axis=-1)))
    return F_J_W, M_J_W, F_size, M_size
