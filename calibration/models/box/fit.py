"""The box model against measured modes: MAC pairing and the RTRI evaluation function.

Each measured mode (frequency and shape at the sensors) is paired with the model mode of
largest MAC (seed eq. 4) among the model's lowest ``n_modes``; the evaluation function is
the largest relative frequency error of the pairs in per cent (seed eq. 3).

A measured mode may carry its half-power band (``ModeTarget.band``, its damping ratio).
Where two or more model modes lie inside that band a single-exciter test cannot separate
them (modal overlap above 1): the identified shape is a mixture of theirs. Such a target
is compared with the span of the model modes in its band (the MAC of the shape with its
projection on that span) and takes the frequency of the member contributing most to the
projection, whenever that beats the best single mode. Without a band, the seed's pairing.

A target given by mode type only (an idealised floor pattern, :mod:`.mode_types`) pairs
with *some* mode however unlike it; ``BoxFit(min_mac=...)`` makes a pairing count only when
sound (MAC at least that, its partner no other target's), else it is penalised.

A swarm is evaluated in one batched reduced eigen-solve (:mod:`.reduced`), on a basis that
:meth:`BoxFit.adapt` rebuilds around the swarm's best as the search narrows; the answer
is always re-solved on the full model (:meth:`BoxFit.full_check`), so the reduced basis's
error is measured, not assumed.

``BoxFit`` also presents the reduced model in the form the CasADi refinement takes
(:func:`calibration.optimisers.refine.refine`): mass I, stiffness K0 + sum p_i K_i in the
reduced coordinates, modes labelled by their measured partner.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from ...signals.modal import mac_matrix
from .assembly import BoxModel
from .factor import factorise
from .parametric_basis import ReducedFamily, full_modes


#: BoxFit.min_mac: what a pairing below the MAC floor adds to its error [%] per unit of
#: shortfall (10 % per 0.01: continuous, so the swarm can climb to sound pairings), and what
#: a target adds whose partner a target of larger MAC has (one mode cannot be two)
MAC_SHORTFALL_PCT = 1000.0
SHARED_PARTNER_PCT = 100.0
#: BoxFit.min_carbody_share: a partner is at least half carbody by kinetic energy, because
#: MAC is blind to amplitude and a bogie mode seen faintly through the suspension can rate as
#: alike as the carbody mode it couples to (docs/methods/calibration-box.md, section 6).
MIN_CARBODY_SHARE = 0.5


@dataclass(frozen=True)
class ModeTarget:
    label: str
    frequency_hz: float
    shape: np.ndarray  # (n_sensors,) real or complex, at the sensors' measured direction
    band: float = 0.0  # half-power band half-width relative to the frequency (the damping ratio); 0: none


def sensor_operator(model: BoxModel, sensors) -> np.ndarray:
    """(n_sensors, n_dof): what each campaign sensor reads (translation along its direction
    at its position) from the model's DOF. A sensor on ``floor`` or ``roof`` sits on the
    panel of that group containing its position; ``side_left`` etc. name a panel."""
    rows = []
    for s in sensors:
        if s.direction not in ("x", "y", "z"):
            raise ValueError(f"sensor {s.name}: the box model reads translations (x, y, z), not {s.direction}")
        hosts = [pn for pn in model.vehicle.panels if pn.name == s.body or pn.group == s.body]
        host = None
        for pn in hosts:
            try:
                pn.local(s.position)
            except ValueError:
                continue
            host = pn
            break
        if host is None:
            raise ValueError(f"sensor {s.name}: no {s.body!r} panel of the model contains position {s.position}")
        rows.append(model.displacement(host.name, s.position)["xyz".index(s.direction)])
    return np.array(rows)


def carbody_mass_matrix(model: BoxModel):
    """The mass matrix with every rigid body's (bogie's) rows and columns zeroed: x^T Mc x
    is the carbody's share of an M-normalised mode's kinetic energy (the mass matrix has
    no coupling between the panels and the rigid bodies)."""
    keep = np.ones(model.n_dof)
    for rb in model.vehicle.bodies:
        keep[model.dof_slices[rb.name]] = 0.0
    D = sp.diags(keep)
    return (D @ model.M @ D).tocsr()


def select_targets(frequency_hz, shapes, *, strength=None, band=(8.0, 20.0), n: int = 6, max_mac: float = 0.3,
                   labels=None) -> tuple[ModeTarget, ...]:
    """The ``n`` strongest modes in ``band``, each with MAC < ``max_mac`` to those already
    chosen, sorted by frequency. ``strength`` per mode defaults to the shape norm at the
    sensors (M-normalised modes: what the grid sees); for a shaker test pass the resonance
    peak of the accelerance, ||phi_s|| |phi_exciter| / (2 zeta): what the test shows."""
    f = np.asarray(frequency_hz, float)
    S = np.asarray(shapes)
    strength = np.linalg.norm(S, axis=0) if strength is None else np.asarray(strength, float)
    order = sorted((k for k in range(f.size) if band[0] <= f[k] <= band[1]), key=lambda k: -strength[k])
    chosen = []
    for k in order:
        if all(mac_matrix(S[:, [k]], S[:, [j]])[0, 0] < max_mac for j in chosen):
            chosen.append(k)
        if len(chosen) == n:
            break
    if len(chosen) < n:
        raise ValueError(f"only {len(chosen)} distinct modes in {band} Hz")
    chosen.sort()
    labels = labels or [f"mode_{i + 1}" for i in range(n)]
    return tuple(ModeTarget(lbl, float(f[k]), S[:, k] / np.abs(S[:, k]).max()) for lbl, k in zip(labels, chosen))


def band_pairing(frequency_hz, phi, shapes, f_target, band, mac, eligible=None):
    """Pair targets with model modes: the single mode of largest ``mac``, or, for a target
    with ``band`` > 0 whose half-power band holds two or more (eligible) model modes, the
    span of those modes when the shape's MAC with its projection on the span is larger.

    Batched over N parameter sets: ``frequency_hz`` (N, m), model shapes at the sensors
    ``phi`` (N, s, m), target ``shapes`` (s, T), ``f_target`` and ``band`` (T,), ``mac``
    (N, T, m) of single modes (0 where not eligible), ``eligible`` (N, m) or None (all).
    Returns (index (N, T) of the partner or of the span's dominant member, its MAC (N, T))."""
    f = np.asarray(frequency_hz, float)
    idx = np.argmax(mac, axis=2)
    best = np.take_along_axis(mac, idx[..., None], 2)[..., 0]
    band = np.asarray(band, float)
    if not np.any(band > 0):
        return idx, best
    f_t = np.asarray(f_target, float)
    inside = np.abs(f[:, None, :] - f_t[None, :, None]) <= (band * f_t)[None, :, None]
    inside &= (band > 0)[None, :, None]
    if eligible is not None:
        inside &= np.asarray(eligible, bool)[:, None, :]
    rows, cols = np.nonzero(inside.sum(axis=2) >= 2)
    counts = inside[rows, cols].sum(axis=1)
    # batched over the pairs with the same number of modes in their band: in a swarm, a band
    # holding a close pair is common (1-2 per particle), and one least-squares call each
    # cost more than the particle's eigen-solve
    for k in np.unique(counts):
        n, t = rows[counts == k], cols[counts == k]
        ks = np.nonzero(inside[n, t])[1].reshape(-1, k)  # (G, k) the band's members, ascending
        U = np.take_along_axis(phi[n], ks[:, None, :], axis=2)
        U = U / np.linalg.norm(U, axis=1, keepdims=True)  # unit columns: c compares contributions
        v = shapes[:, t].T  # (G, s)
        c = np.einsum("gks,gs->gk", np.linalg.pinv(U, rtol=1e-10), v)  # least squares, rank-revealing
        proj = np.einsum("gsk,gk->gs", U, c)
        span_mac = (np.abs(np.einsum("gs,gs->g", np.conj(proj), v)) ** 2
                    / (np.real(np.einsum("gs,gs->g", np.conj(proj), proj) * np.einsum("gs,gs->g", np.conj(v), v))
                       + 1e-300))
        win = span_mac > best[n, t]
        lead = ks[np.arange(len(n)), np.argmax(np.abs(c), axis=1)]
        idx[n[win], t[win]], best[n[win], t[win]] = lead[win], span_mac[win]
    return idx, best


@dataclass(frozen=True)
class Pairing:
    frequency_hz: np.ndarray  # (N, n_targets) model frequency of each target's partner
    mac: np.ndarray  # (N, n_targets)
    index: np.ndarray  # (N, n_targets) model mode number (0 = lowest)


class BoxFit:
    def __init__(self, model: BoxModel, sensors: np.ndarray, targets: tuple[ModeTarget, ...], *,
                 n_modes: int = 30, basis_size: int = 60, derivatives: int = 20,
                 min_carbody_share: float = MIN_CARBODY_SHARE,
                 min_mac: float = 0.0):
        """``sensors`` (n_sensors, n_dof): the operator from DOF to what each sensor reads
        (e.g. floor vertical displacement). ``min_carbody_share``: a model mode is paired
        only if at least this share of its kinetic energy is in the carbody (panels and the
        masses on them); a bogie mode seen faintly through the suspension has the floor
        pattern of its carbody reaction, which MAC, blind to amplitude, can mistake for an
        elastic mode (0: every mode is eligible). ``min_mac``: a pairing is sound only if
        its MAC reaches this and no other target with a larger MAC has the same partner; an
        unsound one is penalised in RTRI eq. 3 (:meth:`errors_pct`)."""
        self.model = model
        self.sensors = np.asarray(sensors, float)
        self.targets = tuple(targets)
        self.shapes = np.column_stack([np.asarray(t.shape) for t in self.targets])
        self.f_target = np.array([t.frequency_hz for t in self.targets])
        self.band = np.array([t.band for t in self.targets], float)
        self.n_modes, self.basis_size, self.derivatives = n_modes, basis_size, derivatives
        self.names = model.names
        self.reduced: ReducedFamily | None = None
        self.centre: np.ndarray | None = None
        self.confirmed = np.inf  # RTRI eq. 3 at the centre on the basis in use
        self.rebuilds = 0
        self.min_carbody_share = float(min_carbody_share)
        self.min_mac = float(min_mac)
        self._M_carbody = carbody_mass_matrix(model) if self.min_carbody_share > 0 else None
        self._solved: dict = {}  # (p's bytes, n) -> the full model's modes there, the last few

    # -- the full model's modes ----------------------------------------------------------
    def _full_modes(self, p, n: int) -> tuple[np.ndarray, np.ndarray]:
        """:func:`full_modes` of this fit's model, the last few points' kept: a point is
        checked on the full model and the basis is then rebuilt there (the swarm's best, a
        refinement round's end), otherwise the same eigen-solve again. The arrays are
        shared, so read-only."""
        key = (np.asarray(p, float).tobytes(), n)
        if key not in self._solved:
            f, X = full_modes(self.model, p, n)
            f.setflags(write=False)
            X.setflags(write=False)
            if len(self._solved) >= 4:
                del self._solved[next(iter(self._solved))]
            self._solved[key] = f, X
        return self._solved[key]

    # -- reduced basis ----------------------------------------------------------------
    def rebuild(self, p) -> None:
        p = np.asarray(p, float)
        self.use(ReducedFamily.build(self.model, p[None, :], modes_per_sample=self.n_modes, size=self.basis_size,
                                     derivatives=self.derivatives,
                                     modes=lambda _, q, n: self._full_modes(q, n)), p)

    def use(self, family: ReducedFamily, centre) -> None:
        """Evaluate on ``family`` from now on (e.g. one basis for a whole parameter box);
        ``centre``: where :meth:`adapt` measures moves from, and where the error it
        compares gains with is taken (exact there for a basis built at the centre)."""
        self.reduced = family
        self._S = self.sensors @ family.V
        if self._M_carbody is not None:
            self._Mc = family.V.T @ (self._M_carbody @ family.V)
        self.centre = np.asarray(centre, float).copy()
        self.confirmed = float(self.evaluation(self.centre[None, :])[0])
        self.rebuilds += 1

    def adapt(self, iteration: int, best, *, force: bool = False, every: int = 25, distance: float = 0.02,
              gain: float = 0.3) -> bool:
        """PSO hook: rebuild around ``best`` when it has moved more than ``distance``
        (largest relative change of a parameter) from the basis centre and either a check
        falls due (every ``every`` iterations) or its error has fallen by more than the
        fraction ``gain`` below the error at the centre: a basis is exact at its centre
        only, and a large gain far from it is just what an artefact of the basis looks like
        (1000 x 1000 on the typed Figure 5 targets, checked every 25 iterations only: 3.58 %
        on the basis at iteration 10, 14.6 % on the full model once rebuilt at iteration 50,
        the swarm collapsed around it by then). With ``force``: whenever the basis is not
        centred at ``best``."""
        moved = np.max(np.abs(np.asarray(best) / self.centre - 1))
        if force:
            if moved == 0:
                return False
        elif moved <= distance or (iteration % every
                                   and self.evaluation(np.asarray(best, float)[None, :])[0]
                                   >= (1 - gain) * self.confirmed):
            return False
        self.rebuild(best)
        return True

    # -- evaluation ---------------------------------------------------------------------
    def pair(self, P) -> Pairing:
        f, Y = self.reduced.modes(np.atleast_2d(P), self.n_modes)
        phi = np.einsum("sr,nrm->nsm", self._S, Y)  # model shapes at the sensors
        share = None if self._M_carbody is None else np.einsum("nrm,rs,nsm->nm", Y, self._Mc, Y)
        idx, best = self._partners(f, phi, share)
        rows = np.arange(len(f))[:, None]
        return Pairing(f[rows, idx], best, idx)

    def _partners(self, f, phi, share):
        """Batched partners of the targets (:func:`band_pairing`) among model modes of
        frequencies ``f`` (N, m) and sensor shapes ``phi`` (N, s, m); ``share`` (N, m): each
        mode's carbody share of kinetic energy, None when not filtering on it."""
        mac = mac_matrix(self.shapes, phi)  # (N, n_targets, n_modes)
        eligible = None
        if share is not None:
            eligible = share >= self.min_carbody_share
            mac = np.where(eligible[:, None, :], mac, 0.0)
        return band_pairing(f, phi, self.shapes, self.f_target, self.band, mac, eligible)

    @staticmethod
    def shared(mac, index) -> np.ndarray:
        """(N, T) True where a target's partner (``index``, (N, T)) is also the partner of a
        target of larger ``mac`` (the first of equals keeps it): one model mode cannot be
        two measured ones."""
        mac, index = np.atleast_2d(mac), np.atleast_2d(index)
        out = np.zeros(mac.shape, bool)
        for i, j in itertools.combinations(range(mac.shape[1]), 2):
            same = index[:, i] == index[:, j]
            out[:, i] |= same & (mac[:, i] <= mac[:, j])
            out[:, j] |= same & (mac[:, j] < mac[:, i])
        return out

    def sound(self, mac, index) -> np.ndarray:
        """(N, T) True where a pairing counts as it is: MAC at least ``min_mac`` and its
        partner its own (:meth:`shared`); without ``min_mac`` every pairing counts."""
        mac = np.atleast_2d(mac)
        if self.min_mac <= 0:
            return np.ones(mac.shape, bool)
        return (mac >= self.min_mac) & ~self.shared(mac, index)

    def errors_pct(self, frequency_hz, mac, index) -> np.ndarray:
        """Each target's |error| [%] (N, T) from its partners' frequencies, MACs and mode
        indices (N, T). With ``min_mac`` a pairing below it adds MAC_SHORTFALL_PCT per unit
        of shortfall, and a target whose partner a target of larger MAC also has adds
        SHARED_PARTNER_PCT, so the swarm is led to sound pairings (:meth:`sound`)."""
        err = 100 * np.abs(np.asarray(frequency_hz) / self.f_target - 1)
        if self.min_mac <= 0:
            return err
        shortfall = np.maximum(self.min_mac - np.atleast_2d(mac), 0.0)
        return err + MAC_SHORTFALL_PCT * shortfall + SHARED_PARTNER_PCT * self.shared(mac, index)

    def evaluation(self, P) -> np.ndarray:
        """RTRI eq. 3 [%] for each parameter row (with ``min_mac``, unsound pairings penalised)."""
        pr = self.pair(P)
        return np.max(self.errors_pct(pr.frequency_hz, pr.mac, pr.index), axis=1)

    __call__ = evaluation

    def full_check(self, p) -> dict:
        """The full model at p: paired frequencies and MACs, and the reduced basis's error."""
        return self._full_check(p)[0]

    def frequency_gradient(self, p) -> tuple[dict, np.ndarray]:
        """:meth:`full_check` at p and the exact derivatives of the partners' frequencies
        over the targets', d (f_k / f_target_k) / d log p_i = p_i x_k^T K_i x_k / (8 pi^2 f_k
        f_target_k) (x_k M-normalised; K linear in p, M independent of it): (check, (T, d))."""
        p = np.asarray(p, float)
        check, f, X = self._full_check(p)
        return check, self._frequency_jacobian(p, f, X, check["index"])

    def gradients(self, p, macs: bool = True) -> tuple[dict, np.ndarray, np.ndarray | None]:
        """:meth:`frequency_gradient` at p and the derivatives of the partners' MACs,
        d MAC_k / d log p_i (T, d), with each target's partner held: the eigenvector
        derivative of Nelson's method in bordered form, [K - w_k^2 M, M x_k; x_k^T M, 0]
        [dx; mu] = [-(K_i - (x_k^T K_i x_k) M) x_k; 0] (one factorisation per partner,
        the d right-hand sides together; exact for a simple eigenvalue; Nelson, AIAA J. 14
        (1976) 1201-1205), then MAC = |a^H S x|^2 / (a^H a |S x|^2) differentiated. A
        target with a half-power band may pair with the span of several modes
        (:func:`band_pairing`), which this does not differentiate: then central
        differences of +-1e-3 in each log factor (2 d more full eigen-solves). Returns
        (check, d (f / f_target) / d log p, d MAC / d log p or None without ``macs``)."""
        p = np.asarray(p, float)
        check, f, X = self._full_check(p)
        G = self._frequency_jacobian(p, f, X, check["index"])
        if not macs:
            return check, G, None
        if np.any(self.band > 0):
            E = 1e-3 * np.eye(p.size)
            J = np.array([self.full_check(p * np.exp(e))["mac"] - self.full_check(p * np.exp(-e))["mac"]
                          for e in E]).T / 2e-3
            return check, G, J
        K, M = self.model.stiffness(p), self.model.M
        J = np.empty((len(self.targets), p.size))
        for t, k in enumerate(check["index"]):
            x = X[:, k]
            Mx = M @ x
            A = sp.bmat([[K - (2 * np.pi * f[k]) ** 2 * M, Mx[:, None]], [Mx[None, :], None]], format="csc")
            Kx = np.column_stack([self.model.K_units[n] @ x for n in self.names])  # (n_dof, d)
            rhs = -(Kx - np.outer(Mx, x @ Kx))
            dX = factorise(A).solve(np.vstack([rhs, np.zeros((1, p.size))]))[:-1] * p
            a, y, dy = self.shapes[:, t], self.sensors @ x, self.sensors @ dX
            c, aa, yy = np.vdot(a, y), np.real(np.vdot(a, a)), float(y @ y)
            J[t] = (2 * np.real(np.conj(c) * (np.conj(a) @ dy)) * yy - abs(c) ** 2 * 2 * (y @ dy)) / (aa * yy**2)
        return check, G, J

    def _frequency_jacobian(self, p, f, X, idx):
        J = np.array([[p[i] * (x @ (self.model.K_units[n] @ x)) for i, n in enumerate(self.names)]
                      for x in X[:, idx].T])
        return J / (8 * np.pi**2 * f[idx][:, None]) / self.f_target[:, None]

    def _full_check(self, p):
        p = np.asarray(p, float)
        f, X = self._full_modes(p, self.n_modes)
        share = None if self._M_carbody is None else np.einsum("dm,dm->m", X, self._M_carbody @ X)[None]
        idx, best = self._partners(f[None], (self.sensors @ X)[None], share)
        idx, best = idx[0], best[0]
        reduced = self.pair(p[None, :])
        error_pct = 100 * (f[idx] / self.f_target - 1)
        scored = self.errors_pct(f[idx][None], best[None], idx[None])[0]
        return {"frequency_hz": f[idx], "mac": best, "index": idx, "error_pct": error_pct,
                "max_error_pct": float(np.max(scored)), "sound": self.sound(best, idx)[0],
                "reduced_frequency_hz": reduced.frequency_hz[0],
                "reduced_vs_full_pct": 100 * (reduced.frequency_hz[0] / f[idx] - 1)}, f, X

    # -- the form the CasADi refinement takes -------------------------------------------------
    @property
    def dofs(self):
        return tuple(range(self.reduced.size))

    @property
    def M0(self):
        return np.eye(self.reduced.size)

    @property
    def K0(self):
        return self.reduced.K0

    @property
    def M_unit(self):
        return {n: np.zeros((self.reduced.size,) * 2) for n in self.names}

    @property
    def K_unit(self):
        return {n: self.reduced.K_units[i] for i, n in enumerate(self.names)}

    def frequencies(self, P) -> dict:
        pr = self.pair(P)
        return {t.label: pr.frequency_hz[:, i] for i, t in enumerate(self.targets)}

    def labelled_mode(self, p, label: str):
        i = [t.label for t in self.targets].index(label)
        f, Y = self.reduced.modes(np.asarray(p, float)[None, :], self.n_modes)
        k = int(self.pair(np.asarray(p, float)[None, :]).index[0, i])
        return float((2 * np.pi * f[0, k]) ** 2), Y[0][:, k]
