"""The least-squares fit of a log run as a model a user can evaluate: identified/least_squares.toml.

The fit is tau = [Y_b(q, q', q''), E(q', tau_R)] beta (harness/identify/torque_id.py): Y_b the columns
`columns` of the joint-torque regressor with friction (10 per link in the model's joint order, then per
drive armature, viscous, Coulomb, offset), evaluated with the model file `model` (the identified model:
its kinematics and each drive's law, whose smoothing velocities shape the Coulomb columns); E the
columns of the families' coefficients (`families`: drive.term) on the rigid-body torque
tau_R = Y_b[:, link] (beta - share)[link] (BaseParameters.link_part: which base parameters hold a
link's inertia, and the drive terms regrouped into them, at the model's values). The file holds every
base parameter's value, standard deviation and the combination of physical parameters it stands for.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

FORMAT = 1


@dataclass(frozen=True, eq=False)
class LeastSquaresFit:
    """What least_squares.toml holds (r base parameters, then e family coefficients): a fit's Estimate
    (harness/identify/lstsq.py; its beta and std) in the file's form, with what evaluating it needs."""

    model: str  # the model file the columns are evaluated with, relative to the file's folder
    columns: np.ndarray  # (r,) indices into the regressor with friction (14 n columns)
    expressions: list[str]  # (r + e,) what each parameter stands for
    beta: np.ndarray  # (r + e,)
    std: np.ndarray  # (r + e,) NaN where not estimable
    link: np.ndarray  # (r,) bool: holds a link's inertial parameter
    share: np.ndarray  # (r,) the drive terms' share in it (subtracted for the rigid-body torque)
    families: list[str]  # (e,) "drive.term", in extra_terms order
    gravity_W: np.ndarray | None = None  # (3,) m/s^2 the fit was made at (base axes); None in a file without it

    def to_toml(self, description: str) -> str:
        import tomli_w

        r = len(self.columns)
        comment = "".join(f"# {line}\n" for line in description.splitlines())
        return comment + "\n" + tomli_w.dumps({"least_squares": {
            "format": FORMAT, "model": self.model,
            **({"gravity": [float(x) for x in self.gravity_W]} if self.gravity_W is not None else {}),
            "parameter": [{"expression": self.expressions[k], "value": float(self.beta[k]),
                           **({"std": float(self.std[k])} if np.isfinite(self.std[k]) else {}),
                           **({"column": int(self.columns[k]), "link": bool(self.link[k]),
                               "drive_share": float(self.share[k])} if k < r else
                              {"family": self.families[k - r]})}
                          for k in range(len(self.beta))]}})

    @classmethod
    def read(cls, path: Path) -> LeastSquaresFit:
        from harness.base.tomlio import InputError, read_toml

        t = read_toml(path).get("least_squares")
        if not isinstance(t, dict) or t.get("format") != FORMAT or not isinstance(t.get("parameter"), list):
            raise InputError(path, "least_squares", f"not a least-squares fit of format {FORMAT}")
        rows = t["parameter"]
        base = [p for p in rows if "column" in p]
        extra = [p for p in rows if "family" in p]
        if base + extra != rows:
            raise InputError(path, "least_squares.parameter", "the base parameters come first, then the families'")
        return cls(str(t["model"]), np.array([p["column"] for p in base], dtype=int),
                   [str(p["expression"]) for p in rows], np.array([float(p["value"]) for p in rows]),
                   np.array([float(p.get("std", np.nan)) for p in rows]),
                   np.array([bool(p["link"]) for p in base]), np.array([float(p["drive_share"]) for p in base]),
                   [str(p["family"]) for p in extra],
                   np.asarray(t["gravity"], dtype=float) if "gravity" in t else None)


class ExportedModel:
    """What an exported model gives a user's code: `joint_names` (its `spec`'s) and the states an
    `inverse_dynamics(q, qd, qdd)` reads, as float arrays (N, n) (harness.api.IdentifiedModel, and
    LeastSquaresModel below)."""

    spec: object

    @property
    def joint_names(self) -> list[str]:
        return self.spec.joint_names

    @staticmethod
    def states(q, qd, qdd) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return tuple(np.atleast_2d(np.asarray(x, dtype=float)) for x in (q, qd, qdd))


@dataclass(frozen=True, eq=False)
class LeastSquaresModel(ExportedModel):
    """The least-squares fit with the model it is evaluated with: `joint_names`, and
    `inverse_dynamics(q, qd, qdd)` ((N, n) each, SI, the model's joint order) its torques."""

    fit: LeastSquaresFit
    spec: object  # RobotSpec: the model file `fit.model`
    gravity_W: np.ndarray

    def inverse_dynamics(self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
        from harness.engines.pinocchio import build_model
        from harness.identify.laws import Law, extra_regressor
        from harness.identify.torque_id import regressor

        q, qd, qdd = self.states(q, qd, qdd)
        f = self.fit
        r = len(f.columns)
        Y = regressor(build_model(self.spec, self.gravity_W), q, qd, qdd, with_friction=True)[:, f.columns]
        laws = tuple(Law.of(fr) for fr in self.spec.frictions)
        if (own := extra_terms_names(laws, self.spec.drive_names)) != f.families:
            raise ValueError(f"the model's friction families' terms ({', '.join(own) or 'none'}) are not the fit's "
                             f"({', '.join(f.families) or 'none'})")
        rigid = (Y[:, f.link] @ (f.beta[:r] - f.share)[f.link]).reshape(q.shape)
        E = extra_regressor(laws, qd, rigid, self.spec.transmission, q=q)
        return (np.hstack([Y, E]) @ f.beta).reshape(q.shape)


def extra_terms_names(laws, names) -> list[str]:
    from harness.identify.laws import extra_terms

    return [f"{names[k]}.{key}" for k, key in extra_terms(laws)]
