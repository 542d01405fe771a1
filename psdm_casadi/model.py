"""PSDMModel: the derived model as data (E, P, base-parameter map) with numpy evaluation and file I/O.

tau_i = y(q, qd, qdd) P[:, :, i] theta, where y_f = prod_h gamma_h^E[h, f] over
gamma = [q; sin q; cos q; qd; qdd], and functions with no velocity or acceleration factor
(the gravity functions) are multiplied by the gravity magnitude g.

A model too large for the monomial table (more than 8 revolute joints, where the number of
functions grows exponentially) has an empty E and P and a ``chain`` instead: its joint tree and
the standard-parameter preimage of the base parameters, evaluated by a recursion
(``psdm_casadi.chain_regressor``). Both kinds answer the same numeric calls.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.sparse

from psdm_casadi.chain_regressor import ChainRegressor
from psdm_casadi.errors import ModelFileError, ShapeError
from psdm_casadi.fileio import atomic_write
from psdm_casadi.monomials import MonomialTree
from psdm_casadi.state_cache import StateCache

MODEL_FORMAT = "psdm-model"
MODEL_VERSION = 1
CHAIN_MODEL_VERSION = 2  # a model with a chain (no monomial table): older releases must refuse it
READABLE_VERSIONS = (MODEL_VERSION, CHAIN_MODEL_VERSION)
#: Samples per block of the regressor's evaluation: its functions, n_functions x this many values (15 MB for the Panda).
REGRESSOR_BLOCK = 64


@dataclass(frozen=True, eq=False)
class PSDMModel:
    """A derived PSDM model.

    Parameters
    ----------
    exponents : array of uint8, shape (5 n_dof, n_functions)
        E: exponents of [q; sin q; cos q; qd; qdd] in each function (alias of the paper's E).
    reduction : array, shape (n_functions, n_base, n_dof)
        P: the reduction matrices, one slice per joint.
    parameter_map : array, shape (n_base, 11 n_dof)
        theta = parameter_map @ standard.ravel(), standard being (n_dof, 11) rows of
        [m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz, Im] (inertia about the link-frame origin).
    base_names : tuple of str, length n_base
    standard_names : tuple of str, length 11 n_dof
    gravity_magnitude : float
        g [m/s^2] multiplying the gravity functions.
    revolute : array of bool, shape (n_dof,)
    robot_name : str
    metadata : dict
        Provenance only (seed, seconds, accuracy); never read by algorithms.
    chain : ChainRegressor or None
        For a model without monomial table (``exponents`` with no column): the joint tree and the
        preimage that evaluate its regressor.
    """

    exponents: np.ndarray
    reduction: np.ndarray
    parameter_map: np.ndarray
    base_names: tuple
    standard_names: tuple
    gravity_magnitude: float
    revolute: np.ndarray
    robot_name: str = "robot"
    metadata: dict = field(default_factory=dict, compare=False)
    chain: ChainRegressor | None = None

    def __post_init__(self):
        exponents = np.asarray(self.exponents, dtype=np.uint8)
        reduction = np.asarray(self.reduction, dtype=float)
        revolute = np.asarray(self.revolute, dtype=bool)
        n = revolute.size
        if exponents.ndim != 2 or exponents.shape[0] != 5 * n:
            raise ShapeError(f"PSDMModel.exponents must have shape (5*{n}, n_functions); got {exponents.shape}.")
        p = exponents.shape[1]
        if reduction.ndim != 3 or reduction.shape[0] != p or reduction.shape[2] != n:
            raise ShapeError(f"PSDMModel.reduction must have shape ({p}, n_base, {n}); got {reduction.shape}.")
        l = reduction.shape[1]
        parameter_map = np.asarray(self.parameter_map, dtype=float)
        if parameter_map.shape != (l, 11 * n):
            raise ShapeError(f"PSDMModel.parameter_map must have shape ({l}, {11 * n}); got {parameter_map.shape}.")
        if len(self.base_names) != l or len(self.standard_names) != 11 * n:
            raise ShapeError("PSDMModel.base_names/standard_names must match the reduction and parameter map sizes.")
        if self.chain is not None and (p != 0 or self.chain.n_dof != n or self.chain.n_base != l):
            raise ShapeError(
                f"PSDMModel.chain must describe {n} joints and {l} base parameters of a model without monomial "
                f"table; got {self.chain.n_dof} joints, {self.chain.n_base} base parameters and {p} functions."
            )
        for name, value in (
            ("exponents", exponents),
            ("reduction", reduction),
            ("parameter_map", parameter_map),
            ("revolute", revolute),
        ):
            value.setflags(write=False)
            object.__setattr__(self, name, value)
        # P as one sparse (n_functions, n_dof * n_base) matrix for fast batch evaluation
        flat = reduction.transpose(0, 2, 1).reshape(p, n * l)
        object.__setattr__(self, "_reduction_sparse", scipy.sparse.csr_matrix(flat))
        object.__setattr__(self, "_regressor_cache", StateCache())  # a recording's regressor, evaluated once
        object.__setattr__(self, "base_names", tuple(self.base_names))
        object.__setattr__(self, "standard_names", tuple(self.standard_names))

    def __eq__(self, other) -> bool:
        """Equal when E, P, the parameter map, names and g are identical (metadata is ignored)."""
        if not isinstance(other, PSDMModel):
            return NotImplemented
        arrays = ("exponents", "reduction", "parameter_map", "revolute")
        return (
            all(np.array_equal(getattr(self, a), getattr(other, a)) for a in arrays)
            and self.base_names == other.base_names
            and self.standard_names == other.standard_names
            and self.gravity_magnitude == other.gravity_magnitude
            and (self.chain is None) == (other.chain is None)
            and (self.chain is None or self.chain.same_as(other.chain))
        )

    __hash__ = None

    # --- sizes and views -------------------------------------------------------------------------
    @property
    def n_dof(self) -> int:
        return self.revolute.size

    @property
    def n_functions(self) -> int:
        """p, the number of monomial functions (0 for a model without monomial table)."""
        return self.exponents.shape[1]

    @property
    def has_monomials(self) -> bool:
        """True for a model with E and P (the sum form); False for one evaluated through its ``chain``."""
        return self.chain is None

    @property
    def n_base(self) -> int:
        return self.reduction.shape[1]

    @property
    def gravity_functions(self) -> np.ndarray:
        """Boolean (n_functions,): functions with no qd or qdd factor (multiplied by g)."""
        n = self.n_dof
        return ~np.any(self.exponents[3 * n :] > 0, axis=0)

    @property
    def gravity_mask(self) -> np.ndarray:
        """Boolean (n_base,): base parameters that appear in gravity terms (the paper's theta_b,grav)."""
        if self.chain is not None:
            return self.chain.gravity_mask
        return np.any(self.reduction[self.gravity_functions] != 0, axis=(0, 2))

    @property
    def n_gravity(self) -> int:
        return int(self.gravity_mask.sum())

    # --- numeric evaluation ---------------------------------------------------------------------
    def _states(self, *arrays):
        out = []
        single = np.asarray(arrays[0]).ndim == 1
        for name, x in zip(("q", "qd", "qdd"), arrays):
            arr = np.atleast_2d(np.asarray(x, dtype=float))
            if arr.shape[1] != self.n_dof:
                raise ShapeError(
                    f"{name} must have shape (n_samples, {self.n_dof}) or ({self.n_dof},); got {np.shape(x)}."
                )
            out.append(arr)
        if len({a.shape[0] for a in out}) != 1:
            raise ShapeError(f"q, qd, qdd must have the same number of samples; got {[a.shape[0] for a in out]}.")
        return out, single

    def functions(self, q, qd, qdd) -> np.ndarray:
        """The p functions y(q, qd, qdd), shape (n_samples, n_functions), gravity ones times g."""
        (q, qd, qdd), _ = self._states(q, qd, qdd)
        return self._functions_transposed(np.concatenate([q, np.sin(q), np.cos(q), qd, qdd], axis=1)).T

    def _functions_transposed(self, gamma) -> np.ndarray:
        """``functions`` transposed (n_functions, n_samples), C-contiguous, of the signals ``gamma``."""
        tree = self.__dict__.get("_monomial_tree")
        if tree is None:  # the evaluation plan of E, built at the first evaluation (monomials.MonomialTree)
            tree = MonomialTree.of(self.exponents)
            object.__setattr__(self, "_monomial_tree", tree)
        y = tree.evaluate_transposed(gamma)
        y[self.gravity_functions] *= self.gravity_magnitude
        return y

    @property
    def state_cache(self) -> StateCache:
        """The memory of evaluated series of states (``regressor``); a caller that evaluates each series once (a
        fleet's daily update, chunk by chunk) sets its ``max_bytes`` to 0 while it runs, so that nothing is kept."""
        return self._regressor_cache

    def regressor(self, q, qd, qdd) -> np.ndarray:
        """Y(q, qd, qdd), shape (n_samples, n_dof, n_base), or (n_dof, n_base) for one state.

        A series of states evaluated before is answered from memory (``state_cache``: identification evaluates
        one recording's regressor several times); the monomial table is evaluated in blocks of
        ``REGRESSOR_BLOCK`` samples, never for the whole series at once."""
        single = np.asarray(q).ndim == 1
        (q, qd, qdd), _ = self._states(q, qd, qdd)
        out = self._regressor_cache.get(self._evaluate_regressor, q, qd, qdd)
        return out[0] if single else out

    def _evaluate_regressor(self, q, qd, qdd) -> np.ndarray:
        if self.chain is not None:
            return self.chain.regressor(q, qd, qdd)
        gamma = np.concatenate([q, np.sin(q), np.cos(q), qd, qdd], axis=1)
        out = np.empty((gamma.shape[0], self.n_dof, self.n_base))
        for start in range(0, gamma.shape[0], REGRESSOR_BLOCK):
            y = self._functions_transposed(gamma[start : start + REGRESSOR_BLOCK])
            block = np.asarray(self._reduction_sparse.T @ y).T
            out[start : start + REGRESSOR_BLOCK] = block.reshape(y.shape[1], self.n_dof, self.n_base)
        return out

    def gravity_regressor(self, q) -> np.ndarray:
        """Y_grav(q): the regressor of the gravity functions only, shape (n_samples, n_dof, n_base)."""
        q = np.asarray(q, dtype=float)
        zeros = np.zeros_like(q)
        return self.regressor(q, zeros, zeros)

    def inverse_dynamics(self, q, qd, qdd, theta) -> np.ndarray:
        """tau = Y theta, shape (n_samples, n_dof) or (n_dof,)."""
        theta = self._theta(theta)
        return self.regressor(q, qd, qdd) @ theta

    def _theta(self, theta):
        theta = np.asarray(theta, dtype=float).reshape(-1)
        if theta.size != self.n_base:
            raise ShapeError(f"theta must have {self.n_base} base parameters; got {theta.size}.")
        return theta

    def base_parameters(self, standard) -> np.ndarray:
        """theta from standard parameters, shape (n_dof, 11) or (11 n_dof,)."""
        standard = np.asarray(standard, dtype=float).reshape(-1)
        if standard.size != self.parameter_map.shape[1]:
            raise ShapeError(
                f"standard parameters must be ({self.n_dof}, 11) [m, mx, my, mz, Ixx, Ixy, Iyy, Ixz, Iyz, Izz, Im]; "
                f"got {standard.size} values."
            )
        return self.parameter_map @ standard

    # --- presentation ---------------------------------------------------------------------------
    def equations(self, digits: int = 4) -> str:
        """The base parameters as sums of standard parameters, like the paper's Table 4.

        Standard parameters are m_i, the first moments m r (``mx``, ``my``, ``mz``), the inertia
        about the link-frame origin (``Ixx`` ...) and the rotor inertia ``Im``.
        """
        lines = []
        gravity = self.gravity_mask
        for j, name in enumerate(self.base_names):
            terms = []
            for coef, std in zip(self.parameter_map[j], self.standard_names):
                if abs(coef) < 1e-12:
                    continue
                sign = "-" if coef < 0 else "+"
                magnitude = abs(coef)
                text = std if abs(magnitude - 1) < 1e-9 else f"{magnitude:.{digits}g}*{std}"
                terms.append((sign, text))
            body = " ".join(f"{s} {t}" for s, t in terms).lstrip("+ ").strip() or "0"
            if body.startswith("- "):
                body = "-" + body[2:]
            kind = "gravity" if gravity[j] else "inertial"
            lines.append(f"{name:>8} [{kind:8}] = {body}")
        return "\n".join(lines)

    def summary(self) -> dict:
        return {
            "robot": self.robot_name,
            "n_dof": self.n_dof,
            "form": "sum" if self.has_monomials else "recursive",
            "p": self.n_functions if self.has_monomials else None,
            "l": self.n_base,
            "n_gravity": self.n_gravity,
        }

    # --- files ----------------------------------------------------------------------------------
    def save(self, path, overwrite: bool = False) -> Path:
        """Write the model to a versioned ``.npz`` file atomically; refuse to overwrite unless asked.

        The arrays are zip-compressed: the reduction tensor is mostly zeros (the Panda's 64 MB become 0.2 MB,
        and read faster); ``load_model`` reads compressed and uncompressed files alike.
        """
        path = Path(path)
        if path.suffix != ".npz":
            path = path.with_suffix(path.suffix + ".npz") if path.suffix else path.with_suffix(".npz")
        header = {
            "format": MODEL_FORMAT,
            "version": MODEL_VERSION if self.chain is None else CHAIN_MODEL_VERSION,
            "robot_name": self.robot_name,
            "base_names": list(self.base_names),
            "standard_names": list(self.standard_names),
            "gravity_magnitude": self.gravity_magnitude,
            "metadata": self.metadata,
        }
        atomic_write(
            path,
            lambda handle: np.savez_compressed(
                handle,
                header=np.array(json.dumps(header)),
                exponents=self.exponents,
                reduction=self.reduction,
                parameter_map=self.parameter_map,
                revolute=self.revolute,
                **({} if self.chain is None else self.chain.arrays()),
            ),
            overwrite=overwrite,
            mode="wb",
        )
        return path


def load_model(path) -> PSDMModel:
    """Read a model written by ``PSDMModel.save``.

    Raises
    ------
    ModelFileError
        When the file is not a psdm-casadi model or has an unsupported version.
    """
    path = Path(path)
    if not path.exists():
        raise ModelFileError(f"model file {str(path)!r} does not exist. Check the path or run 'psdm derive -o'.")
    try:
        with np.load(path, allow_pickle=False) as data:
            header = json.loads(str(data["header"]))
            arrays = {k: data[k] for k in ("exponents", "reduction", "parameter_map", "revolute")}
            chain = ChainRegressor.from_arrays(data) if header.get("version") == CHAIN_MODEL_VERSION else None
    except (OSError, ValueError, KeyError) as exc:
        raise ModelFileError(f"{path.name} is not a psdm-casadi model file ({exc}).") from None
    if header.get("format") != MODEL_FORMAT:
        raise ModelFileError(f"{path.name}: format must be {MODEL_FORMAT!r}; got {header.get('format')!r}.")
    if header.get("version") not in READABLE_VERSIONS:
        raise ModelFileError(
            f"{path.name}: model version {header.get('version')} is not supported (this release reads "
            f"versions {', '.join(map(str, READABLE_VERSIONS))}). Derive the model again with this release."
        )
    return PSDMModel(
        exponents=arrays["exponents"],
        reduction=arrays["reduction"],
        parameter_map=arrays["parameter_map"],
        base_names=tuple(header["base_names"]),
        standard_names=tuple(header["standard_names"]),
        gravity_magnitude=float(header["gravity_magnitude"]),
        revolute=arrays["revolute"],
        robot_name=header["robot_name"],
        metadata=header.get("metadata", {}),
        chain=chain,
    )
