# ------------------------------------------------------------------------------------------------
# The identification method: an object with `joint_names` and `fit(q, qd, qdd, tau)` returning the
# identified model (a model as above). Where the identified model has `parameters`, (n, 10): per
# joint the child body's [m, m c, I_xx, I_xy, I_yy, I_xz, I_yz, I_zz] about the joint point in
# world axes at q = 0, the harness compares its base parameters with the robot's; with
# `covariance` (10 n, 10 n) of those parameters, it also reports intervals and their coverage.
# Here: ordinary least squares on Pinocchio's joint-torque regressor of the robot file, with each
# joint's viscous and Coulomb friction (URDF's <dynamics damping friction>, MJCF's damping and
# frictionloss): any robot of revolute, continuous and prismatic joints. A joint's armature (MJCF) is
# taken as known, as are the drives where your model file states them ([drives]: motors behind the
# joints through a transmission N); the rest is fitted.


class Drives:
    """Your model file's drives as the harness reads them (harness/model/drives.py): each motor's law
    reaching the joints through N (tau = N^T f_m(N q', N q'')), and the rotors' mass matrix
    N^T diag(I_m) N. `of(robot)` is None for a robot without drives."""

    def __init__(self, robot):
        from harness.model import drives

        self.robot, self.law = robot, drives
        self.mass = drives.mass(robot.frictions, robot.transmission)

    @classmethod
    def of(cls, robot):
        return None if getattr(robot, "transmission", None) is None else cls(robot)

    def torque(self, qd, qdd, tau_rigid, q=None):
        """The drives' torque at the joints; tau_rigid read by a load-dependent law, q by a spring."""
        return self.law.torque(self.robot.frictions, self.robot.transmission, qd, qdd, tau_rigid, q)


def springs(robot) -> dict:
    """{joint: (k, k springref)}: the springs of a robot without drives (an MJCF joint's stiffness), which
    Pinocchio's parser does not read; with drives they are the drives' (Drives)."""
    if getattr(robot, "transmission", None) is not None:
        return {}
    return {j.name: (j.friction.stiffness, -j.friction.offset) for j in robot.joints if j.friction.stiffness}


def spring_terms(springs, joint_names) -> tuple[np.ndarray, np.ndarray]:
    """(k, k springref), each (n,) in the order of `joint_names`, of `springs` (`springs(robot)`, or None)."""
    spring = [(springs or {}).get(j, (0.0, 0.0)) for j in joint_names]
    return np.array([s[0] for s in spring]), np.array([s[1] for s in spring])


class LeastSquares:
    def __init__(self, path, gravity_W, drives=None, springs=None):
        self.drives = drives  # known: the fit is of what they leave
        pin = self.pin = _pinocchio()
        self.model, self.data, self.joint_names = robot_model(path, gravity_W)
        self.armature = np.array(self.model.armature)  # known: the regressor holds the links alone
        self.stiffness, self.spring_rest = spring_terms(springs, self.joint_names)  # known: an MJCF joint's spring
        # theta_W = A theta_J: each body's parameters from its joint frame to world axes at q = 0
        pin.forwardKinematics(self.model, self.data, pin.neutral(self.model))
        n = self.model.njoints - 1
        self.A = np.zeros((10 * n, 10 * n))
        for j in range(n):
            R = self.data.oMi[j + 1].rotation
            for k in range(10):
                self.A[10 * j: 10 * j + 10, 10 * j + k] = _rotate_parameters(R, np.eye(10)[k])

    def regressor(self, q, qd, qdd):
        """(N n, 12 n): rows sample by sample, columns the 10 inertial parameters of every joint's
        body (in its joint frame), then every joint's viscous and Coulomb coefficients."""
        W = np.concatenate([self.pin.computeJointTorqueRegressor(self.model, self.data, a, b, c)
                            for a, b, c in zip(configuration(self.model, q), qd, qdd, strict=True)])
        N, n = qd.shape
        F, j = np.zeros((N, n, 2 * n)), np.arange(n)
        F[:, j, j], F[:, j, n + j] = qd, np.sign(qd)
        return np.hstack([W, F.reshape(N * n, 2 * n)])

    def known(self, q, qd, qdd):
        """The torques the method does not fit: the joints' armature and the drives' law (a
        load-dependent law, which reads the rigid bodies' torque, is not known here)."""
        tau = self.armature * qdd + self.stiffness * q - self.spring_rest
        return tau if self.drives is None else tau + self.drives.torque(qd, qdd, None, q)

    def fit(self, q, qd, qdd, tau):
        tau = tau - self.known(q, qd, qdd)
        W, y = self.regressor(q, qd, qdd), tau.reshape(-1)
        # W = U diag(s) V^T, kept to its numerical rank (numpy's and lstsq's cut-off): the minimum-norm
        # solution theta = V diag(1/s) U^T y, exact on the base parameters, and its covariance
        # sigma^2 (W^T W)^+ = sigma^2 V diag(1/s^2) V^T, made from V alone (pinv(W^T W) is not symmetric
        # to round-off on a robot of 32 joints)
        U, s, Vt = np.linalg.svd(W, full_matrices=False)
        rank = int(np.sum(s > s[0] * max(W.shape) * np.finfo(float).eps))
        V = Vt[:rank].T / s[:rank]
        theta = V @ (U[:, :rank].T @ y)
        sigma2 = np.sum((y - W @ theta) ** 2) / max(len(y) - rank, 1)
        k = self.A.shape[0]  # the inertial parameters, turned to world axes; the friction stays the method's own
        cov = self.A @ (sigma2 * V[:k] @ V[:k].T) @ self.A.T
        return Fitted(self, theta, self.A @ theta[:k], (cov + cov.T) / 2)  # symmetric to the bit


class Fitted:
    def __init__(self, method, theta, theta_W, cov_W):
        self.method, self.theta = method, theta
        self.joint_names = method.joint_names
        self.parameters = theta_W.reshape(-1, 10)
        self.covariance = cov_W

    def inverse_dynamics(self, q, qd, qdd):
        return (self.method.regressor(q, qd, qdd) @ self.theta).reshape(q.shape) + self.method.known(q, qd, qdd)


def _pinocchio():
    import pinocchio

    return pinocchio


def robot_model(path, gravity_W):
    """Pinocchio's model of the robot file (a URDF, or an MJCF file: told by the root element) with the
    scenario's gravity, its data, and its joints' names in its order. Pinocchio's own parser reads it,
    given an MJCF file with what that parser cannot read made readable (keyframes left out, several
    root bodies under one), a ball joint as the three hinges the harness reads it as, and a floating base
    held where the file puts it, as the harness holds it (harness/engines/pinocchio_file.py)."""
    from harness.engines.pinocchio_file import parse

    model, _ = parse(Path(path), ball_hinges=True)
    model.gravity.linear = np.asarray(gravity_W, dtype=float)
    return model, model.createData(), list(model.names)[1:]


def configuration(model, q):
    """Pinocchio's configuration (N, nq) of joint angles and positions q (N, nv): a continuous joint
    is held as (cos q, sin q)."""
    out = np.empty((len(q), model.nq))
    for j in range(1, model.njoints):
        iq, iv = model.joints[j].idx_q, model.joints[j].idx_v
        if model.joints[j].nq == 2:
            out[:, iq], out[:, iq + 1] = np.cos(q[:, iv]), np.sin(q[:, iv])
        else:
            out[:, iq] = q[:, iv]
    return out


def _rotate_parameters(R, theta):
    """[m, h, I about the origin] of a frame turned by R: m, R h, R I R^T."""
    xx, xy, yy, xz, yz, zz = theta[4:]
    J = R @ np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]]) @ R.T
    return np.concatenate([[theta[0]], R @ theta[1:4], [J[0, 0], J[0, 1], J[1, 1], J[0, 2], J[1, 2], J[2, 2]]])


def make_method(robot, gravity_W, parameters):
    return LeastSquares(Path(__file__).parent / parameters.get("robot_file", ROBOT_FILE), gravity_W, Drives.of(robot),
                        springs(robot))
