"""Newton's method with an LU (band, dense or sparse), optional factorisation reuse and a
globalising line search (:func:`newton`).

The unknown is a plain vector ``u`` on the free DOFs; the caller's ``evaluate(u)`` returns the
residual (and, on request, the iteration matrix). Reuse (``reuse_factorization``): the LU of an
earlier iterate is kept while the model's active set (slack/taut threads, contacts) is
unchanged; otherwise it is refreshed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import Any, Callable

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from numpy.typing import NDArray
from scipy.linalg.lapack import dgbtrf as _gbtrf, dgbtrs as _gbtrs, dgetrf as _getrf, dgetrs as _getrs

from rodnet.assembly import (DENSE_LIMIT, BandedMatrix, IterationMatrix, add_diagonal,
                             diagonal)
from rodnet.sparse_lu import Pattern, StaticPatternLU, same_pattern

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, slots=True)
class NewtonOptions:
    """Tolerances and limits of :func:`newton`.

    The residual is converged when ``|r|_inf <= atol + rtol * scale`` (``atol`` at most ``rtol *
    scale``: :func:`tolerance`), or when a full Newton
    correction moves no node by more than ``xtol`` times the length scale and turns none by
    more than ``xtol`` rad. A solve fails when it makes no progress (in ``stall_iterations``
    iterations its correction not halved and its merit not lowered by 1e-6 of itself), when its
    residual stands (``standing_iterations``) or when it reaches ``max_iterations``; a
    converging solve is not cut short before that. With
    ``progress_iterations`` set, a solve that has taken twice that many iterations also fails
    when its Euclidean residual has not halved (from where it last did) for that many: a
    search creeping down the potential (linear convergence on rotation nodes of almost no
    stiffness) costs more than the step taken again at half the size, which adaptive runs do.
    ``reuse_factorization``: an iterate whose residual fell to 0.3 of the last one's, with the
    same active set (slack and taut threads, contacts), takes its correction from the last
    factorisation.
    """

    rtol: float = 1e-8
    atol: float = 1e-10
    max_iterations: int = 200
    reuse_factorization: bool = False
    max_rotation: float = np.pi / 4
    xtol: float = 1e-7
    stall_iterations: int = 25
    progress_iterations: int | None = None
    mixed: bool = True
    """Newton's matrix takes the stresses of the strains linearised along the last correction
    (the mixed Newton step, :mod:`rodnet.integrate.mixed`) in its geometric stiffness."""
    min_step: float = 2.0**-20
    """The smallest step fraction the line search tries before the solve fails."""
    armijo: float = 1e-4
    """Sufficient decrease of the merit function per unit of its slope."""
    standing_iterations: int | None = 50
    """A solve fails when its Euclidean residual has not fallen below ``1 - STANDING`` of its
    lowest for this many iterations, whatever the merit does (None: never): with velocity forces
    outside the potential (friction) a search can lower the potential without end at a standing
    residual (61.5 N to three digits for 190 iterations on a cable sliding on a box, until the
    200-iteration limit)."""
    restrain: bool = True
    """A correction that turns nodes by more than ``max_rotation`` is solved again with those
    nodes' rotations restrained (:func:`_restrained`), so that the rest of the correction
    answers the shorter turns, before the rotations left too long are cut; and a step whose
    rotations were cut is not taken as the watchdog's free step. False: rotations are only
    cut, and any full step may be the free one."""


@dataclass
class NewtonResult:
    u: FloatArray
    converged: bool
    iterations: int
    factorizations: int
    residual_norm: float
    message: str = ""
    singular: bool = False
    """The solve failed because an iteration matrix could not be factorised."""
    discarded_iterations: int = 0
    """Iterations of earlier solves of the same step from other starts that failed; counted in
    the run's totals, not in ``iterations`` (which the step-size control reads)."""
    discarded_factorizations: int = 0
    """Factorisations of those failed solves."""

    def add_counts(self, earlier: NewtonResult) -> None:
        """Count an earlier solve of the same step in this one: its iterations and
        factorisations in these, its discarded ones in the discarded."""
        self.iterations += earlier.iterations
        self.factorizations += earlier.factorizations
        self.discarded_iterations += earlier.discarded_iterations
        self.discarded_factorizations += earlier.discarded_factorizations


class LinearSolver:
    """LU of the iteration matrix, kept between calls until refreshed.

    A CSR matrix is factorised by dense LAPACK below ``dense_limit`` unknowns and above by the
    fixed-pattern sparse LU of :mod:`rodnet.sparse_lu` once its pattern has come twice in a row
    (the analysis is then reused for every later matrix of that pattern), by SuperLU otherwise
    and whenever the fixed-pattern LU meets a (nearly) zero pivot. A model may instead hand over
    its matrix already in LAPACK's band storage (:class:`~rodnet.assembly.BandedMatrix`) or as a
    dense array, which are factorised as given.
    """

    dense_limit = DENSE_LIMIT

    def __init__(self) -> None:
        self.lu: Any = None
        self.factorizations = 0
        self._static: StaticPatternLU | None = None
        self._seen_pattern: Pattern | None = None
        self._unsymmetric: Pattern | None = None   # a pattern the fixed-pattern LU refused

    def factorize(self, matrix: IterationMatrix) -> None:
        """Factorise. A band matrix is factorised in place (its storage is overwritten), a dense
        one on a copy. For SuperLU the symmetric ordering with diagonal pivots suits the (nearly
        symmetric, pattern-symmetric) tangents, partial pivoting is its fall-back.

        Raises
        ------
        FloatingPointError
            When the matrix holds a NaN or an infinity.
        RuntimeError
            When the matrix is exactly singular.
        """
        self.factorizations += 1
        if isinstance(matrix, BandedMatrix):
            self.lu = _BandLU(matrix)
            return
        if isinstance(matrix, np.ndarray):
            self.lu = _DenseLU(matrix)
            return
        if not np.isfinite(matrix.data).all():  # SuperLU can loop forever on NaN
            raise FloatingPointError("non-finite iteration matrix")
        if matrix.shape[0] <= self.dense_limit:
            self.lu = _DenseLU(matrix.toarray())
            return
        static = self._static_lu(matrix)
        if static is not None and static.factorize(matrix):
            self.lu = static
            return
        if _empty_line(matrix):
            # SuperLU finds such a matrix singular too, but prints BLAS errors on the way (a
            # static net lying in a coordinate plane: its nodes held by slack threads only)
            raise RuntimeError("Factor is exactly singular")
        csc = matrix.tocsc()
        try:
            self.lu = spla.splu(csc, permc_spec="MMD_AT_PLUS_A", diag_pivot_thresh=0.0,
                                options={"SymmetricMode": True})
            probe = np.ones(csc.shape[0])
            if np.isfinite(self.lu.solve(probe)).all():
                return
        except RuntimeError:
            pass
        self.lu = spla.splu(csc)  # raises RuntimeError when exactly singular

    def solve(self, rhs: FloatArray) -> FloatArray:
        assert self.lu is not None
        return self.lu.solve(rhs)

    def _static_lu(self, matrix: sp.csr_matrix) -> StaticPatternLU | None:
        """The fixed-pattern LU for ``matrix``'s pattern, analysed when the same pattern comes a
        second time in a row (a pattern seen once may never come back); None for a pattern it
        cannot take (not structurally symmetric), which is then not analysed again."""
        if self._static is not None and self._static.matches(matrix):
            return self._static
        if same_pattern(self._unsymmetric, matrix):
            return None
        seen, self._seen_pattern = self._seen_pattern, (matrix.indptr, matrix.indices)
        if not same_pattern(seen, matrix):
            return None
        try:
            self._static = StaticPatternLU(matrix)
        except ValueError:  # not structurally symmetric
            self._static, self._unsymmetric = None, (matrix.indptr, matrix.indices)
        return self._static


def _empty_line(matrix: sp.csr_matrix) -> bool:
    """Whether some row or column of ``matrix`` holds only zeros (it is then singular)."""
    nonzero = matrix.data != 0.0
    rows = np.repeat(np.arange(matrix.shape[0]), np.diff(matrix.indptr))
    return bool(len(np.unique(rows[nonzero])) < matrix.shape[0]
                or len(np.unique(matrix.indices[nonzero])) < matrix.shape[1])


class _DenseLU:
    """LAPACK's LU with partial pivoting of a dense (n, n) matrix, with SuperLU's ``solve``."""

    def __init__(self, matrix: FloatArray) -> None:
        if not np.isfinite(matrix).all():
            raise FloatingPointError("non-finite iteration matrix")
        lu, piv, info = _getrf(matrix)
        if info > 0 or not np.isfinite(lu).all():
            raise RuntimeError("Factor is exactly singular")
        self.lu, self.piv = lu, piv

    def solve(self, rhs: FloatArray) -> FloatArray:
        return _getrs(self.lu, self.piv, rhs)[0]


class _BandLU:
    """LAPACK's band LU with partial pivoting of a :class:`~rodnet.assembly.BandedMatrix`, with
    SuperLU's ``solve``; the band storage is factorised in place."""

    def __init__(self, matrix: BandedMatrix) -> None:
        if not np.isfinite(matrix.ab).all():
            raise FloatingPointError("non-finite iteration matrix")
        self.lower, self.upper, self.order = matrix.lower, matrix.upper, matrix.order
        self.lu, self.piv, info = _gbtrf(matrix.ab, self.lower, self.upper, overwrite_ab=1)
        if info > 0:
            raise RuntimeError("Factor is exactly singular")

    def solve(self, rhs: FloatArray) -> FloatArray:
        x = np.empty_like(rhs)
        x[self.order] = _gbtrs(self.lu, self.lower, self.upper, rhs[self.order], self.piv)[0]
        return x


Evaluate = Callable[[FloatArray, "str | None"], tuple[FloatArray, IterationMatrix | None]]
"""``evaluate(u, matrix) -> (r, S)``: the residual at ``u`` and, for ``matrix = "exact"``, the
iteration matrix ``dr/du``; for ``"convex"`` one whose symmetric part is positive definite
(the model's convexified element blocks: a direction of descent where the exact one gives
none); for ``None`` no matrix."""


@dataclass
class NewtonProblem:
    """``r(u) = 0`` with what :func:`newton` needs besides the residual.

    Attributes
    ----------
    evaluate : Evaluate
    shorten : callable, optional
        ``shorten(du) -> du``: the correction with every rotation increment longer than
        ``max_rotation`` cut to it, node by node.
    small : callable, optional
        ``small(du) -> bool``: the correction moves the configuration by less than the
        tolerances, so the iterate plus it is the solution.
    merit : callable, optional
        ``merit(u)`` whose gradient is ``r`` up to small velocity terms (the step's incremental
        potential); None where there is none (the line search then measures ``|r|^2 / 2``).
    weights : (n,) float, optional
        Scales of the unknowns for the size of a correction.
    on_accept : callable, optional
        Told every accepted iterate.
    active_set : callable, optional
        Fingerprint of the non-smooth state at ``u`` (for factorisation reuse).
    metric : (n,) float, optional
        Positive masses of the unknowns, for the Levenberg-Marquardt shift.
    length : float
        The structure's size [m] (the reach of the first shifted step).
    restraint : callable, optional
        ``restraint(du) -> (n,) float or None``: for every DOF of a node that ``du`` turns by
        ``turn`` > ``max_rotation``, ``turn / max_rotation - 1``, zero elsewhere; None when no
        node turns that far (see :func:`_restrained`).
    rebases : bool
        ``on_accept`` moves the chart ``u`` is read in (a static solve's base): an iterate's
        merit is then computed when the iterate is made, not when first asked.
    on_start : callable, optional
        Told the start instead of ``on_accept`` (it was extrapolated, not reached by a
        correction).
    residual_weights : (n,) float, optional
        Weights of the residual's entries in the convergence test ``|w r|_inf <= tol`` (and
        the residual norm reported): equations of a smaller force scale than the tolerance's
        (a free body beside stiff threads) are solved to their own.
    to_residual : bool
        A correction below the step-size test ends the solve only once the residual no longer
        halves (its round-off floor) or meets the tolerance: for static equilibria, whose forces
        are the result (a stiff cable's nodes were left 0.26 % of their weight out of balance
        by corrections of 1e-13 m, its reactions 0.26 % high).
    """

    evaluate: Evaluate
    shorten: Callable[[FloatArray], FloatArray] | None = None
    small: Callable[[FloatArray], bool] | None = None
    merit: Callable[[FloatArray], float] | None = None
    weights: FloatArray | None = None
    on_accept: Callable[[FloatArray], None] | None = None
    active_set: Callable[[FloatArray], Any] | None = None
    metric: FloatArray | None = None
    length: float = 1.0
    restraint: Callable[[FloatArray], FloatArray | None] | None = None
    rebases: bool = False
    on_start: Callable[[FloatArray], None] | None = None
    residual_weights: FloatArray | None = None
    to_residual: bool = False


def tolerance(options: NewtonOptions, scale: float) -> float:
    """Newton's residual tolerance [N] for forces of size ``scale`` [N]: ``atol + rtol scale``
    with the absolute part at most the relative one, so that loads far below ``atol`` (a
    micrometre filament under piconewtons) are still solved to ``rtol`` of themselves."""
    relative = options.rtol * scale
    return min(options.atol, relative) + relative


def newton(problem: NewtonProblem, u0: FloatArray, scale: float, solver: LinearSolver,
           options: NewtonOptions, history: list[float] | None = None) -> NewtonResult:
    """Solve ``r(u) = 0`` by Newton's method, globalised for minimisation.

    Every iteration takes the correction ``du = -S^-1 r`` of the exact iteration matrix ``S``;
    where it turns nodes by more than ``max_rotation`` it is solved again with those rotations
    restrained (``restrain``, :func:`_restrained`), and rotations still too long are cut to
    ``max_rotation`` node by node. Steps are judged by a merit ``phi``:
    the step's incremental potential where the system has one (its gradient is the residual up
    to velocity terms such as gyroscopic moments), else ``|r|^2 / 2``. A trial ``u + a du``
    decreases ``phi`` sufficiently when ``phi(u + a du) <= phi(u) + armijo a slope`` (Armijo;
    ``slope = r . du``, or ``-|r|^2`` for ``|r|^2 / 2``); when ``phi`` changes by no more
    than its round-off while ``|r|`` falls by ``a / 4`` of itself (near the solution); or,
    without a potential, when the simplified correction there is shorter by that fraction
    (Deuflhard's natural monotonicity test). A full step is also taken when it brings the
    Euclidean residual to half the smallest one of the solve so far, though ``phi`` rises
    (:func:`_halves_residual`: near a root that is not ``phi``'s minimum).

    Watchdog (Chamberlain, Powell, Lemarechal and Pedersen 1982): a full step that does not
    decrease ``phi`` is taken anyway (unless rotations were cut in it: that step is no longer
    Newton's, and its other parts answer turns it does not make), and within :data:`WATCHDOG_STEPS` further full steps,
    each decreasing ``phi`` from where it starts, ``phi`` must fall below the point before the
    free step; otherwise the iteration returns there and backtracks (``a = 1/2, ..., 1/64``).
    A stiff thread turned by a large rotation is stretched by the linearised step (``phi`` and
    ``|r|`` jump up) and relaxed by the next: a monotone search would cut that step short.

    Where backtracking fails, the step comes from the convexified matrix ``H`` (element blocks
    projected on the positive semidefinite ones, ``evaluate(u, "convex")``) shifted by ``mu
    diag(|H_ii|)`` (Levenberg-Marquardt), ``mu`` raised until the potential decreases; without
    a potential, from ``H`` with a backtracking search down to ``min_step``; where no step
    lowers the potential, from the Levenberg-Marquardt correction of ``|r|^2 / 2``
    (:func:`_residual_descent`: the potential's gradient is the residual only up to terms no
    potential gives, so it can stall away from a root). Near a solution
    full exact steps are taken, so with consistent tangents the convergence is quadratic. A
    matrix is factorised at accepted points only; a converged iterate is polished with the
    last factorisation.

    The solve has converged when ``|r|_inf <=`` :func:`tolerance` or a correction is
    ``small``. It fails on a non-finite residual, when no step decreases ``phi``, when for
    ``stall_iterations`` iterations neither ``phi`` fell nor the correction halved, when for
    ``progress_iterations`` (if set) the Euclidean residual did not halve (after at least
    twice as many iterations), or after
    ``max_iterations``.
    """
    p = problem
    start = solver.factorizations
    tol = tolerance(options, scale)
    w = np.ones_like(u0) if p.weights is None else p.weights
    here = _point(p, np.array(u0, dtype=float), None)
    count = {"iterations": 0}

    def done(at: _Point, ok: bool, message: str = "", singular: bool = False) -> NewtonResult:
        return NewtonResult(at.u, ok, count["iterations"], solver.factorizations - start,
                            at.norm, message, singular)

    if not math.isfinite(here.norm):
        return done(here, False, "non-finite residual")
    if history is not None:
        history.append(here.norm)
    # a start within the tolerance still takes one correction (where it has a residual and a
    # matrix): the tolerance's force scale has a floor of 1 % of the largest EA, which on small
    # vibrations (a steel cantilever swinging by 0.1 mm) is a tenth of the forces acting, and
    # predictors accepted unsolved made BDF2 and generalized-alpha gain and lose energy that
    # the energy guard then took out (outside check)
    within = here.norm <= tol
    if within and here.norm == 0.0:
        return done(here, True)
    told = p.on_accept if p.on_start is None else p.on_start
    if told is not None:   # the start is the first iterate
        told(here.u)
    if not _direction(p, solver, here, "exact", options):
        if within:
            return done(here, True)
        if not here.potential:
            return done(here, False, "the iteration matrix cannot be factorised", True)
        here.du = None   # a singular matrix (a slack cable at rest): a shifted step first
    watch: _Point | None = None      # the point before a step taken without decrease
    free = True                      # a free step may be taken (none failed since a full one)
    # kept between iterations: the last Levenberg-Marquardt factor that served ("mu") and the
    # smallest Euclidean residual reached ("residual", :func:`_halves_residual`)
    memory: dict[str, float] = {"residual": _length(here.r)}
    watched = 0                      # monotone steps taken since the free one
    best, since_best = math.inf, 0
    mark, since_mark = _length(here.r), 0   # the residual last halved, and iterations since
    low, since_low = _length(here.r), 0     # the residual's lowest, and iterations since
    while count["iterations"] < options.max_iterations:
        if here.du is not None and p.small is not None and p.small(here.du):
            final = _point(p, here.u + here.du, None)
            count["iterations"] += 1
            if history is not None:
                history.append(final.norm)
            if not p.to_residual or final.norm <= tol or not final.norm < 0.5 * here.norm or \
                    not _direction(p, solver, final, "exact", options):
                return done(final, True)
            here = final   # the residual still halves: not yet at its floor (to_residual)
            if p.on_accept is not None:
                p.on_accept(here.u)
            continue
        count["iterations"] += 1
        if here.du is None:
            nxt, watch = _levenberg(p, solver, here, options, memory), None
            if nxt is None:
                nxt = _residual_descent(p, solver, here, options, memory)
        else:
            # without a potential, the natural monotonicity test and the free step accept
            # rises of |r|: where the residual has stood, only decreases from here on
            strict = not here.potential and since_low >= CYCLE_ITERATIONS
            nxt, watch, free, watched = _next(p, solver, here, options, w, watch, free,
                                              watched, memory, strict)
        if nxt is None:
            origin = here if watch is None else watch
            return done(origin, False, f"no step along the Newton correction reduces the "
                        f"residual {origin.norm:.3g} N (tolerance {tol:.3g} N)",
                        here.du is None)
        size = _length(w * (nxt.u - here.u))
        previous, here = here, nxt
        length = _length(here.r)
        memory["residual"] = min(memory["residual"], length)
        if p.merit is not None and not here.potential:
            p = replace(p, merit=None)   # the potential gave out: |r|^2 / 2 from here on
        if history is not None:
            history.append(here.norm)
        if here.norm <= tol:
            return done(_polished(p, solver, here), True)
        if length < (1.0 - STANDING) * low:
            low, since_low = length, 0
        else:
            since_low += 1
            if options.standing_iterations is not None and \
                    since_low >= options.standing_iterations:
                return done(here, False, f"stalled: the residual stood at {here.norm:.3g} N for "
                            f"{since_low} iterations")
        if length <= 0.5 * mark:
            mark, since_mark = length, 0
        else:
            since_mark += 1
            if options.progress_iterations is not None and \
                    since_mark >= options.progress_iterations and \
                    count["iterations"] >= 2 * options.progress_iterations:
                return done(here, False, f"no progress: the residual did not halve in "
                            f"{since_mark} iterations (residual {here.norm:.3g} N)")
        reuse = (options.reuse_factorization and p.active_set is not None
                 and _length(here.r) <= 0.3 * _length(previous.r)
                 and p.active_set(here.u) == p.active_set(previous.u))
        if not (reuse and _kept_direction(p, solver, here)) and \
                not _direction(p, solver, here, "exact", options):
            if not here.potential:
                return done(here, False, "the iteration matrix cannot be factorised", True)
            here.du = None
        if p.on_accept is not None:
            p.on_accept(here.u)
        if size < 0.5 * best or here.phi < previous.phi - 1e-6 * abs(previous.phi):
            best, since_best = min(best, size), 0
        else:
            since_best += 1
            if since_best >= options.stall_iterations:
                return done(here, False, f"stalled: residual {here.norm:.3g} N after "
                            f"{count['iterations']} iterations")
    return done(here, False, f"no convergence in {options.max_iterations} iterations "
                f"(residual {here.norm:.3g} N, tolerance {tol:.3g} N)")


CYCLE_ITERATIONS = 10
"""Iterations without a new lowest Euclidean residual after which a solve without a potential
takes only steps that decrease its merit ``|r|^2 / 2`` (:func:`_next`, ``strict``): a cable
thread landing on a box with friction at a fixed BDF2 step cycled between 0.489 and 0.524 N
(the natural monotonicity test accepting the rise, Armijo the fall) until the iteration
limit."""

STANDING = 1e-3
"""A residual stands while it stays above ``1 - STANDING`` of its lowest
(``NewtonOptions.standing_iterations``)."""

LEVENBERG_START = 1e-4
"""The first factor ``mu`` of the Levenberg-Marquardt shift ``mu diag(|H_ii|)`` (no metric)."""

LEVENBERG_REACH = 0.01
"""With a metric, the first shifted step moves the most accelerated node by about this fraction
of the structure's size."""

LEVENBERG_TRIES = 20
"""Factors tried, each four times the last, before the shifted step is given up."""

WATCHDOG_STEPS = 3
"""Steps after a free one that may decrease the merit from where they start without yet
bringing it below the point before the free step."""


@dataclass
class _Point:
    """An iterate: ``u``, its residual, merit ``phi`` (computed by ``measure`` when first
    asked: a full step that halves the residual is taken without it) and (once computed)
    Newton correction."""

    u: FloatArray
    r: FloatArray
    norm: float
    measure: Callable[[], float] = field(repr=False)
    potential: bool
    du: FloatArray | None = field(default_factory=lambda: np.zeros(0))
    step: FloatArray = field(default_factory=lambda: np.zeros(0))
    slope: float = 0.0

    @cached_property
    def phi(self) -> float:
        return self.measure()


def _point(p: NewtonProblem, u: FloatArray, near: _Point | None) -> _Point:
    """The iterate at ``u`` with its residual and merit."""
    r, _ = p.evaluate(u, None)
    norm = _max_abs(r if p.residual_weights is None else p.residual_weights * r)
    merit = p.merit
    if not math.isfinite(norm):
        return _Point(u, r, norm, lambda: math.inf, merit is not None)
    if merit is None:
        return _Point(u, r, norm, lambda: 0.5 * _dot(r, r), False)
    point = _Point(u, r, norm, lambda: merit(u), True)
    if p.rebases:
        point.phi  # noqa: B018  (taken now, in the chart the iterate was made in)
    return point


def _direction(p: NewtonProblem, solver: LinearSolver, at: _Point, matrix: str,
               options: NewtonOptions) -> bool:
    """Factorise the ``matrix`` ("exact" or "convex") at ``at`` and store its correction
    (restrained where it turns nodes too far, :func:`_restrained`), the shortened step and the
    merit's slope along it; False when it cannot be factorised."""
    _, S = p.evaluate(at.u, matrix)
    curved = at.potential and matrix == "exact"
    restrain = _restrains(p, options)
    # a band matrix is factorised in place
    original = _copy(S) if restrain else S
    try:
        solver.factorize(S)
    except (FloatingPointError, RuntimeError):
        return False
    du = -solver.solve(at.r)
    if not np.isfinite(du).all():
        return False
    if curved and _dot(du, at.r) >= 0.0:
        # du . S du = -du . r <= 0: the potential curves down along du (an indefinite matrix,
        # whose correction heads for a saddle or a maximum); the convexified matrix's heads
        # downhill
        return _direction(p, solver, at, "convex", options)
    if restrain:
        du = _restrained(p, solver, original, at.r, du)
    at.du = du
    at.step = du if p.shorten is None else p.shorten(du)
    at.slope = _slope(p, at, du, matrix)
    return True


def _slope(p: NewtonProblem, at: _Point, du: FloatArray, matrix: str) -> float:
    """The merit's slope along ``at.step``: ``r . step`` for the potential (its gradient is
    ``r``); for ``|r|^2 / 2``, ``r . (J step)``, which along an exact Newton step is ``-|r|^2``
    (the cut step scales it), and along another (the convexified matrix's) takes the exact
    matrix ``J``. (``r . step`` there mixed the units of force and force squared: a scene in
    force units 1e5 times smaller failed its line search where the original converged.)"""
    if at.potential:
        return _dot(at.r, at.step)
    if matrix == "exact":
        return -_dot(at.r, at.r) * _ratio(at.step, du)
    _, J = p.evaluate(at.u, "exact")
    return _dot(at.r, _sparse(J) @ at.step) if J is not None else math.nan


def _next(p: NewtonProblem, solver: LinearSolver, here: _Point, options: NewtonOptions,
          w: FloatArray, watch: _Point | None, free: bool, watched: int,
          memory: dict[str, float], strict: bool = False
          ) -> tuple[_Point | None, _Point | None, bool, int]:
    """One iteration from ``here``: the full Newton step, the watchdog, backtracking and the
    shifted convexified step, in that order (see :func:`newton`). Returns the next iterate
    (None when none decreases the merit) and the watchdog's state ``watch, free, watched``.
    ``strict``: no free step, and no natural monotonicity test (only Armijo decreases of the
    merit and the residual filter): steps that raise the merit cannot then cycle."""
    natural = None if strict else solver
    trial = _point(p, here.u + here.step, here)
    if watch is None and (_halves_residual(trial, memory)
                          or _decreases(trial, here, 1.0, options, natural, w)):
        return trial, None, True, watched
    cut = (_restrains(p, options) and here.du is not None
           and not np.array_equal(here.step, here.du))   # still cut after the restraint
    if watch is None and free and not strict and not cut and math.isfinite(trial.norm):
        return trial, here, free, 0                    # the watchdog's free step
    if watch is not None and _decreases(trial, watch, 1.0, options):
        return trial, None, True, watched              # the free step paid off
    if (watch is not None and watched < WATCHDOG_STEPS
            and _decreases(trial, here, 1.0, options, solver, w)):
        return trial, watch, free, watched + 1         # on its way down: a while longer
    origin = here if watch is None else watch          # back to where the search began
    free = free and watch is None                      # no free step again before a full one
    if origin is not here and p.on_accept is not None:
        p.on_accept(origin.u)    # the caller's chart (a static solve's base) goes back too
    nxt = _backtrack(p, origin, 1.0 / 64.0, options, natural if origin is here else None, w) \
        if origin.slope < 0.0 else None
    if nxt is None and origin.potential:
        nxt = _levenberg(p, solver, origin, options, memory)
    if nxt is None and _direction(p, solver, origin, "convex", options) and origin.slope < 0.0:
        nxt = _backtrack(p, origin, options.min_step, options, None, w)
    if nxt is None and origin.potential:
        nxt = _residual_descent(p, solver, origin, options, memory)
    return nxt, None, free, watched


RESIDUAL_FILTER = 0.5
"""A full step is also taken when its residual is at most this fraction of the smallest one
the solve has reached (:func:`_halves_residual`)."""


def _halves_residual(trial: _Point, memory: dict[str, float]) -> bool:
    """Whether ``trial`` lowers the Euclidean residual to :data:`RESIDUAL_FILTER` of the
    smallest one of the solve so far (``memory["residual"]``).

    The potential's gradient is the residual only up to terms no potential gives (the rotated
    momenta of the sections, damping at the step's strain rates); its minimum then lies a
    little off the root, and near it the full Newton step, which heads for the root, raises the
    potential: a search on the potential alone creeps along its valley (the pinned Cosserat net
    at a 1.6 ms BDF2 step: 300 iterations at a residual of 1e-2 N). Taking the full step where
    it halves the smallest residual keeps the quadratic convergence; it cannot cycle, since
    each such step halves a bound that no other step raises. A non-finite residual compares
    false."""
    return _length(trial.r) <= RESIDUAL_FILTER * memory["residual"]


def _restrains(p: NewtonProblem, options: NewtonOptions) -> bool:
    """Whether corrections that turn nodes too far are solved again restrained (the option is
    on and the problem says which nodes turn too far)."""
    return options.restrain and p.restraint is not None


def _restrained(p: NewtonProblem, solver: LinearSolver, S: IterationMatrix, r: FloatArray,
                du: FloatArray) -> FloatArray:
    """The correction solved again with the rotations it turns too far restrained: the
    diagonal of ``S`` at every DOF of a node that ``du`` turns by ``turn > max_rotation`` is
    raised by ``(turn / max_rotation - 1) |S_ii|`` (``p.restraint``), a Levenberg-Marquardt
    shift on those nodes alone; ``du`` itself when no node turns that far, or when the
    restrained matrix cannot be factorised or its correction does not head downhill.

    Where a node of little stiffness against turning (the end of a slack, crumpled thread
    element, the section of a thread about its own axis) would turn by radians, cutting its
    rotation alone leaves the rest of the correction answering a turn that is not made (the
    neighbouring positions are moved for it), and the cut step raises the residual; the
    restrained correction is consistent with the shorter turn. The shift brings a node whose
    own diagonal dominates its equations to the cap; nodes that turn through a mode far softer
    than their diagonals are held shorter (validation/benchmarks/results/newton_restraint.md:
    loosening the shift there was tried and not kept). The factorisation left in ``solver``
    is the restrained one (used only by the polishing of a converged iterate, which needs a
    correction only near the solution, where nothing is restrained)."""
    factor = p.restraint(du)   # called only where _restrains(p, options)
    if factor is None:
        return du
    try:
        solver.factorize(add_diagonal(S, factor * np.abs(diagonal(S))))
    except (FloatingPointError, RuntimeError):
        return du
    restrained = -solver.solve(r)
    if not np.isfinite(restrained).all() or _dot(r, restrained) >= 0.0:
        return du
    return restrained


def _polished(p: NewtonProblem, solver: LinearSolver, at: _Point) -> _Point:
    """``at`` moved by the correction of the last factorisation, when that lowers the residual:
    a converged iterate is polished for the price of one solve (momentum-conserving schemes
    conserve momentum to the residual left)."""
    polished = _point(p, at.u - solver.solve(at.r), at)
    return polished if polished.norm < at.norm else at


def _copy(S: IterationMatrix) -> IterationMatrix:
    """A copy of ``S`` that survives its factorisation (band storage is factorised in place)."""
    if isinstance(S, BandedMatrix):
        return BandedMatrix(np.array(S.ab, order="F"), S.lower, S.upper, S.order)
    return S


def _kept_direction(p: NewtonProblem, solver: LinearSolver, at: _Point) -> bool:
    """The correction of the kept factorisation at ``at`` (``reuse_factorization``)."""
    du = -solver.solve(at.r)
    if not np.isfinite(du).all():
        return False
    at.du = du
    at.step = du if p.shorten is None else p.shorten(du)
    at.slope = _dot(at.r, at.step) if at.potential else -_dot(at.r, at.r) * _ratio(at.step, du)
    return True


def _ratio(step: FloatArray, du: FloatArray) -> float:
    """The fraction of ``du`` that ``step`` (``du`` with rotations cut) keeps, in its norm."""
    full = _length(du)
    return _length(step) / full if full > 0.0 else 1.0


def _decreases(trial: _Point, at: _Point, alpha: float, options: NewtonOptions,
               solver: LinearSolver | None = None, w: FloatArray | None = None) -> bool:
    """Whether ``trial`` = ``at + alpha step`` decreases the merit sufficiently (Armijo), or,
    with ``phi`` unchanged to its round-off, the residual by ``alpha / 4`` of itself. Without a
    potential, given the factorisation at ``at`` (``solver``), also when the simplified
    correction there, ``-S^-1 r(trial)``, is shorter than ``(1 - alpha / 4) |du|`` in the norm
    of ``w`` (Deuflhard's natural monotonicity test, invariant to the scaling of the
    equations)."""
    if not math.isfinite(trial.phi):
        return False
    if at.slope < 0.0 and trial.phi <= at.phi + options.armijo * alpha * at.slope:
        return True
    bound = 1.0 - 0.25 * alpha
    roundoff = 1e-12 * max(abs(at.phi), abs(trial.phi))
    if abs(trial.phi - at.phi) <= roundoff and _length(trial.r) <= bound * _length(at.r):
        return True
    if solver is None or trial.potential or w is None:
        return False
    return _length(w * solver.solve(trial.r)) <= bound * _length(w * at.du)


def _levenberg(p: NewtonProblem, solver: LinearSolver, at: _Point, options: NewtonOptions,
               memory: dict[str, float]) -> _Point | None:
    """A step that decreases the potential from ``at``: the correction of the convexified
    matrix ``H`` shifted by ``mu D`` (Levenberg-Marquardt), ``mu`` raised fourfold until the
    full step decreases the potential sufficiently.

    ``D`` is the diagonal mass ``metric`` where the problem gives one: ``(H + mu M) du = -r``
    is then a step of pseudo-time ``1 / sqrt(mu)`` of the damped dynamics that relax to the
    minimum (pseudo-transient continuation), which also moves parts that have no stiffness
    yet (a slack cable at rest). The first ``mu`` lets the most accelerated node move 1 % of
    the structure's size; later calls start from the last factor that served, divided by
    four. Without a metric, ``D = diag(|H_ii|)`` (Marquardt's scaling). A large shift shortens
    the step and turns it towards steepest descent, which tames the near-singular directions
    of a convexified matrix (a thread's spin about its own axis between pinned knots)."""
    _, H = p.evaluate(at.u, "convex")
    if p.metric is not None:
        scale = np.asarray(p.metric, dtype=float)
        if "mu" not in memory:
            acceleration = float(np.max(np.abs(at.r) / scale))
            memory["mu"] = acceleration / (LEVENBERG_REACH * p.length)
    else:
        scale = np.abs(diagonal(H))
        scale = np.maximum(scale, 1e-12 * float(scale.max(initial=0.0)))
        memory.setdefault("mu", LEVENBERG_START)
    found = _shifted(p, solver, H, scale, at.r, memory["mu"], at, lambda x: x.phi, options)
    if found is None:
        return None
    trial, at.du, mu = found
    memory["mu"] = mu / 4.0
    return trial


def _shifted(p: NewtonProblem, solver: LinearSolver, A: IterationMatrix, scale: FloatArray,
             gradient: FloatArray, mu: float, at: _Point, merit: Callable[[_Point], float],
             options: NewtonOptions) -> tuple[_Point, FloatArray, float] | None:
    """The first correction ``du = -(A + mu diag(scale))^-1 gradient``, ``mu`` raised fourfold
    up to :data:`LEVENBERG_TRIES` times, whose step (rotations cut) from ``at`` lowers
    ``merit`` sufficiently (Armijo along ``gradient``, the merit's gradient); the trial point
    (of ``p``), ``du`` and the ``mu`` that served, or None."""
    start = merit(at)
    for _ in range(LEVENBERG_TRIES):
        try:
            solver.factorize(add_diagonal(A, mu * scale))
        except (FloatingPointError, RuntimeError):
            mu *= 4.0
            continue
        du = -solver.solve(gradient)
        step = du if p.shorten is None else p.shorten(du)
        slope = _dot(gradient, step)
        if np.isfinite(du).all() and slope < 0.0:
            trial = _point(p, at.u + step, at)
            value = merit(trial)
            if math.isfinite(value) and value <= start + options.armijo * slope:
                return trial, du, mu
        mu *= 4.0
    return None


def _residual_descent(p: NewtonProblem, solver: LinearSolver, at: _Point,
                      options: NewtonOptions, memory: dict[str, float]) -> _Point | None:
    """A step that decreases ``|r|^2 / 2`` from ``at`` where no step decreases the potential:
    the Levenberg-Marquardt correction ``(S^T S + mu D) du = -S^T r`` of the exact matrix ``S``
    (``D = diag(S^T S)``), ``mu`` raised fourfold until the step (rotations cut) decreases
    ``|r|^2 / 2`` sufficiently; the point returned is judged by ``|r|^2 / 2`` (``potential``
    false), and so is the rest of the solve.

    The potential's gradient is the residual only up to terms that no potential gives
    (gyroscopic moments, and ``T(dq)^T`` on rotation increments): after long turns within a
    step, no step may lower the potential although the residual is far from zero. ``S`` is the
    residual's Jacobian, so for a large ``mu`` the correction heads down ``|r|^2 / 2`` (Nocedal
    and Wright 2006, section 10.3), and the rest of the solve takes Newton steps judged by
    ``|r|^2 / 2``."""
    _, S = p.evaluate(at.u, "exact")
    J = _sparse(S)
    gradient = J.T @ at.r
    if not np.isfinite(gradient).all() or not gradient.any():
        return None
    normal = (J.T @ J).tocsr()
    scale = normal.diagonal()
    scale = np.maximum(scale, 1e-12 * float(scale.max(initial=0.0)))
    found = _shifted(replace(p, merit=None), solver, normal, scale, gradient,
                     memory.get("residual_mu", LEVENBERG_START), at,
                     lambda x: 0.5 * _dot(x.r, x.r), options)
    if found is None:
        return None
    memory["residual_mu"] = found[2] / 4.0
    return found[0]


def _sparse(S: IterationMatrix) -> sp.csr_matrix:
    """``S`` (CSR, band or dense storage) as a CSR matrix."""
    return S.tocsr() if isinstance(S, BandedMatrix) else sp.csr_matrix(S)


def _backtrack(p: NewtonProblem, at: _Point, smallest: float, options: NewtonOptions,
               solver: LinearSolver | None, w: FloatArray) -> _Point | None:
    """The first trial ``at + a step``, ``a = 1/2, 1/4, ..., smallest``, that decreases the
    merit sufficiently (:func:`_decreases`, with ``solver`` factorised at ``at`` if given); for
    the convexified correction from ``a = 1``."""
    alpha = 0.5 if smallest > options.min_step else 1.0
    while alpha >= smallest:
        trial = _point(p, at.u + alpha * at.step, at)
        if _decreases(trial, at, alpha, options, solver, w):
            return trial
        alpha *= 0.5
    return None


def _max_abs(r: FloatArray) -> float:
    """``max |r_i|`` (0 for an empty vector)."""
    return float(np.abs(r).max()) if r.size else 0.0


def _dot(x: FloatArray, y: FloatArray) -> float:
    """``x . y`` without BLAS: a threaded BLAS ``ddot`` waits for a core to come free, which
    on a busy machine costs milliseconds per call."""
    return float(np.einsum("i,i", x, y))


def _length(x: FloatArray) -> float:
    """Euclidean norm of a vector."""
    return math.sqrt(_dot(x, x))
