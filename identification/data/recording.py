"""Recording: sampled joint positions with torques and/or motor currents, the input of every identification step.

A recording comes from a robot (``io.load_recording``) or from the virtual robot
(``synthetic.simulate_recording``); ``preprocessing.preprocess`` filters it and adds velocities and
accelerations; ``Recording.split`` cuts it into training and validation parts.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from psdm_casadi.errors import RecordingError, ShapeError

MIN_SAMPLES = 3  # the fewest samples central differences can work on

_KEEP = object()  # sentinel of ``Recording.with_signals``: keep the current value


def _frozen(array) -> np.ndarray:
    """A read-only float array nobody else can write: a copy, unless ``array`` already is one.

    An array that owns its data and is already read-only (another Recording's, or one a reader made
    for this Recording) is kept as is: a 2.5 M-sample recording is then held once, not twice.
    """
    if isinstance(array, np.ndarray) and array.dtype == np.float64 and array.base is None:
        if not array.flags.writeable:
            return array
    out = np.array(array, dtype=float, copy=True)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class Recording:
    """Joint positions and torques (or motor currents) sampled over time.

    Parameters
    ----------
    t : array, shape (n_samples,)
        Sample times [s], strictly increasing; the steps may be uneven.
    q : array, shape (n_samples, n_dof)
        Joint positions [rad or m].
    tau : array, shape (n_samples, n_dof), optional
        Joint (motor-side, reflected) torques [N m or N].
    current : array, shape (n_samples, n_dof), optional
        Motor currents [A]; joint torque is ``Kt * current`` (paper eq. 11).
    qd : array, shape (n_samples, n_dof), optional
        Joint velocities [rad/s], measured or from ``preprocess``.
    qdd : array, shape (n_samples, n_dof), optional
        Joint accelerations [rad/s^2], usually from ``preprocess``.
    name : str
        Where the recording came from (a file name, an experiment); used in messages.
    missing_torque : tuple of (int, str)
        ``(joint, why)`` pairs, 0-based: joints whose torque (or current) column carries no measurement (a dead
        sensor channel). Their columns are NaN; the fit and the validation leave those joints' rows of this
        recording out and keep the other joints' (``missing_torque.find_missing_torque`` detects them). A
        ``tau`` or ``current`` column that is NaN in every sample is marked so by itself.
    temperature : array, shape (n_samples, n_dof), optional
        Each joint's logged temperature [°C] (``data.temperature``): a controller logs it slowly, so NaN between
        its readings (or throughout, for a joint it does not log) is kept; only an infinite value is refused.

    Raises
    ------
    ShapeError
        When an array does not have the shape above.
    RecordingError
        When a value is NaN or infinite (other than a whole missing torque column), time does not increase,
        there are fewer than 3 samples, or neither ``tau`` nor ``current`` is given.

    Examples
    --------
    >>> import numpy as np
    >>> t = np.linspace(0.0, 1.0, 1001)
    >>> q = np.column_stack([np.sin(t), np.cos(t)])
    >>> rec = Recording(t=t, q=q, tau=np.zeros_like(q))
    >>> train, validation = rec.split(0.85)
    >>> train.n_samples, validation.n_samples
    (851, 150)
    """

    t: np.ndarray
    q: np.ndarray
    tau: np.ndarray | None = None
    current: np.ndarray | None = None
    qd: np.ndarray | None = None
    qdd: np.ndarray | None = None
    name: str = ""
    missing_torque: tuple = ()
    temperature: np.ndarray | None = None

    def __post_init__(self):
        where = f" ({self.name})" if self.name else ""
        t = np.asarray(self.t, dtype=float)
        if t.ndim != 1:
            raise ShapeError(f"Recording.t must have shape (n_samples,); got {t.shape}{where}. Pass a 1-D time array.")
        n = t.shape[0]
        if n < MIN_SAMPLES:
            raise RecordingError(
                f"Recording.t must hold at least {MIN_SAMPLES} samples; got {n}{where}. Record a longer experiment."
            )
        q = np.asarray(self.q, dtype=float)
        if q.ndim == 1:
            q = q[:, None]
        if q.ndim != 2 or q.shape[0] != n:
            hint = " Pass q.T." if q.ndim == 2 and q.shape[1] == n else ""
            raise ShapeError(
                f"Recording.q must have shape (n_samples, n_dof) with n_samples={n} to match Recording.t; "
                f"got {q.shape}{where}.{hint}"
            )
        n_dof = q.shape[1]
        _check_finite("t", t, where)
        steps = np.diff(t)
        if np.any(steps <= 0):
            k = int(np.argmax(steps <= 0)) + 1
            raise RecordingError(
                f"Recording.t must be strictly increasing; got t[{k}]={t[k]!r} after t[{k - 1}]={t[k - 1]!r}{where}. "
                "Sort the samples and drop repeated time stamps."
            )
        object.__setattr__(self, "t", _frozen(t))
        _check_finite("q", q, where)
        object.__setattr__(self, "q", _frozen(q))
        for key in ("tau", "current", "qd", "qdd"):
            value = getattr(self, key)
            if value is None:
                continue
            arr = np.asarray(value, dtype=float)
            if arr.ndim == 1 and n_dof == 1:
                arr = arr[:, None]
            if arr.shape != (n, n_dof):
                hint = f" Pass {key}.T." if arr.shape == (n_dof, n) else ""
                raise ShapeError(
                    f"Recording.{key} must have shape (n_samples, n_dof) = ({n}, {n_dof}) to match Recording.q; "
                    f"got {arr.shape}{where}.{hint}"
                )
            if key in ("tau", "current"):
                arr = self._mark_missing(key, arr, n_dof)
            missing = [j for j, _ in self.missing_torque] if key in ("tau", "current") else ()
            _check_finite(key, arr, where, missing)
            object.__setattr__(self, key, _frozen(arr))
        if self.temperature is not None:
            object.__setattr__(self, "temperature", _frozen(_checked_temperature(self.temperature, n, n_dof, where)))
        if self.tau is None and self.current is None:
            raise RecordingError(
                f"Recording needs joint torques or motor currents; got neither{where}. Pass tau= or current=."
            )

    def _mark_missing(self, key: str, arr: np.ndarray, n_dof: int) -> np.ndarray:
        """``arr`` with the missing joints' columns NaN; a column NaN throughout joins ``missing_torque``."""
        missing = {}
        for joint, why in self.missing_torque:
            if not (isinstance(joint, (int, np.integer)) and 0 <= joint < n_dof):
                raise RecordingError(
                    f"Recording.missing_torque must name joints 0..{n_dof - 1}; got {joint!r}. Give 0-based joints."
                )
            missing.setdefault(int(joint), str(why))
        for joint in np.flatnonzero(np.all(np.isnan(arr), axis=0)):
            missing.setdefault(int(joint), "NaN in every sample")
        if len(missing) == n_dof:
            raise RecordingError(
                f"Recording.{key} holds no measurement: every joint's column is NaN or marked missing "
                f"({self.name or 'recording'}). Check the {key} columns (--columns)."
            )
        object.__setattr__(self, "missing_torque", tuple(sorted(missing.items())))
        if missing and not np.all(np.isnan(arr[:, sorted(missing)])):
            arr = arr.copy()
            arr[:, sorted(missing)] = np.nan
        return arr

    # --- views -----------------------------------------------------------------------------------
    @property
    def n_samples(self) -> int:
        return int(self.t.shape[0])

    @property
    def n_dof(self) -> int:
        return int(self.q.shape[1])

    @property
    def duration(self) -> float:
        """Time from the first to the last sample [s]."""
        return float(self.t[-1] - self.t[0])

    @property
    def dt(self) -> float:
        """Median sample step [s]."""
        return float(np.median(np.diff(self.t)))

    def is_uniform(self, rtol: float = 1e-6) -> bool:
        """Whether every time step equals the median one within ``rtol`` (relative)."""
        steps = np.diff(self.t)
        return bool(np.all(np.abs(steps - self.dt) <= rtol * self.dt))

    def joint_torque(self, kt=None, joint: int | None = None) -> np.ndarray:
        """Joint torques [N m]: ``tau`` if recorded, else ``kt * current`` (paper eq. 11).

        Parameters
        ----------
        kt : array, shape (n_dof,), optional
            Motor torque constants [N m/A]; needed when only currents were recorded.
        joint : int, optional
            Only this joint's column (0-based), shape (n_samples,): what a column-by-column preparation needs
            without a copy of every joint.

        Returns
        -------
        array, shape (n_samples, n_dof)

        Raises
        ------
        ParameterError
            When only currents were recorded and ``kt`` is missing or of the wrong length.
        """
        columns = slice(None) if joint is None else joint
        if self.tau is not None and kt is None:
            return self.tau[:, columns].copy()
        if self.current is None:
            return self.tau[:, columns].copy()
        if kt is None:
            raise RecordingError(
                "Recording.tau is absent, so Recording.joint_torque needs kt; got kt=None. "
                "Pass the motor torque constants kt (n_dof,) [N m/A]."
            )
        kt = np.asarray(kt, dtype=float).reshape(-1)
        if kt.shape != (self.n_dof,):
            raise ShapeError(
                f"Recording.joint_torque kt must have shape ({self.n_dof},) to match Recording.n_dof; got {kt.shape}."
            )
        return self.current[:, columns] * kt[columns]

    def check_robot(self, n_dof: int, robot_name: str = "RobotDescription") -> Recording:
        """Check the recording has one column per joint of a robot; return it unchanged.

        Raises
        ------
        ShapeError
            Naming the shapes and the fix, e.g. ``Pass q.T.``
        """
        if self.n_dof != n_dof:
            hint = " Pass q.T." if self.n_samples == n_dof else " Record every joint of the robot."
            raise ShapeError(
                f"Recording.q must have shape (n_samples, {n_dof}) to match {robot_name}.n_dof={n_dof}; "
                f"got {self.q.shape}.{hint}"
            )
        return self

    # --- derived recordings -------------------------------------------------------------------
    def with_signals(self, *, t=_KEEP, q=_KEEP, tau=_KEEP, current=_KEEP, qd=_KEEP, qdd=_KEEP, name=_KEEP,
                     temperature=_KEEP) -> Recording:  # fmt: skip
        """A copy with some signals replaced (pass ``None`` to drop an optional one)."""
        given = dict(t=t, q=q, tau=tau, current=current, qd=qd, qdd=qdd, name=name, temperature=temperature)
        changes = {key: value for key, value in given.items() if value is not _KEEP}
        return replace(self, **changes)

    def with_tau(self, tau) -> Recording:
        """A copy with joint torques ``tau`` (n_samples, n_dof) [N m]."""
        return self.with_signals(tau=tau)

    def slice(self, start: int | None = None, stop: int | None = None) -> Recording:
        """Samples ``start:stop`` (Python slice semantics) as a new recording."""
        index = slice(start, stop)
        return self._take(index)

    def time_slice(self, t_start: float = -np.inf, t_stop: float = np.inf) -> Recording:
        """Samples with ``t_start <= t < t_stop`` as a new recording."""
        mask = (self.t >= t_start) & (self.t < t_stop)
        return self._take(np.flatnonzero(mask))

    def _take(self, index) -> Recording:
        def pick(a):
            return None if a is None else a[index]

        return Recording(
            t=self.t[index],
            q=self.q[index],
            tau=pick(self.tau),
            current=pick(self.current),
            qd=pick(self.qd),
            qdd=pick(self.qdd),
            name=self.name,
            missing_torque=self.missing_torque,
            temperature=pick(self.temperature),
        )

    def split(self, fraction: float = 0.85, n_blocks: int = 1) -> tuple[Recording, Recording]:
        """Training and validation parts in contiguous blocks (paper: 85/15 %).

        The recording is cut into ``n_blocks`` equal contiguous blocks; the first ``fraction`` of each
        block goes to training, the rest to validation. With ``n_blocks=1`` the validation part is the
        last 15 % of the recording. Split after ``preprocess`` so differences see contiguous samples.

        Parameters
        ----------
        fraction : float
            Share of samples for training, in (0, 1).
        n_blocks : int
            Number of contiguous blocks, >= 1.

        Returns
        -------
        (Recording, Recording)
            Training and validation recordings.

        Raises
        ------
        ParameterError
            When ``fraction`` is outside (0, 1), ``n_blocks`` < 1, or a part would hold fewer than 3 samples.
        """
        if not 0.0 < fraction < 1.0:
            raise RecordingError(f"Recording.split fraction must be in (0, 1); got {fraction!r}. Use e.g. 0.85.")
        if not (isinstance(n_blocks, (int, np.integer)) and n_blocks >= 1):
            raise RecordingError(f"Recording.split n_blocks must be an integer >= 1; got {n_blocks!r}.")
        edges = np.linspace(0, self.n_samples, n_blocks + 1).round().astype(int)
        train, validation = [], []
        for lo, hi in zip(edges[:-1], edges[1:]):
            cut = lo + int(round(fraction * (hi - lo)))
            train.append(np.arange(lo, cut))
            validation.append(np.arange(cut, hi))
        train, validation = np.concatenate(train), np.concatenate(validation)
        if min(train.size, validation.size) < MIN_SAMPLES:
            raise RecordingError(
                f"Recording.split fraction={fraction} with n_blocks={n_blocks} leaves {train.size} training and "
                f"{validation.size} validation samples; each part needs at least {MIN_SAMPLES}. "
                "Use a longer recording, fewer blocks or a fraction nearer 0.5."
            )
        return self._take(train), self._take(validation)


def _check_finite(key: str, arr: np.ndarray, where: str, missing=()) -> None:
    bad = ~np.isfinite(arr)
    if missing:  # the missing joints' columns are NaN by design
        bad[:, list(missing)] = False
    if np.any(bad):
        index = np.argwhere(bad)[0]
        row = int(index[0])
        column = key if arr.ndim == 1 else f"{key}{int(index[1]) + 1}"
        raise RecordingError(
            f"Recording.{key} must be finite; got {float(arr[tuple(index)])!r} in column {column} "
            f"at sample {row}{where}. "
            "Remove or interpolate the bad samples."
        )


def _checked_temperature(value, n: int, n_dof: int, where: str) -> np.ndarray:
    """The temperatures as (n_samples, n_dof), NaN kept (readings between slow samples), an infinite value refused."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 1 and n_dof == 1:
        arr = arr[:, None]
    if arr.shape != (n, n_dof):
        raise ShapeError(f"Recording.temperature must have shape (n_samples, n_dof) = ({n}, {n_dof}) to match "
                         f"Recording.q; got {arr.shape}{where}.")  # fmt: skip
    if np.any(np.isinf(arr)):
        row, column = (int(k) for k in np.argwhere(np.isinf(arr))[0])
        raise RecordingError(f"Recording.temperature must be finite or NaN (not logged at that sample); got "
                             f"{float(arr[row, column])!r} in column temp{column + 1} at sample {row}{where}. "
                             "Remove the bad readings.")  # fmt: skip
    return arr
