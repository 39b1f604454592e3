"""The small SDP of the E relaxation, max t s.t. B0 + sum_i w_i B_i - t I >= 0, by its own interior point.

A primal-dual path-following method for this small SDP (k x k LMI, m
weights): HKM search direction with Mehrotra's predictor-corrector,
infeasible start, the Newton system reduced to the (m + 1) x (m + 1)
Schur complement M_ij = tr(A_i X A_j Z^-1) plus the diagonal of the linear
inequalities (Helmberg, Rendl, Vanderbei & Wolkowicz, SIAM J. Optim. 6
(1996) 342-361; Todd, Toh & Tutuncu, SIAM J. Optim. 8 (1998) 769-796).  In
the dual standard form max b^T y s.t. Z = C - sum_j y_j A_j >= 0, y = (w, t),
C = B0, A_i = -B_i, A_t = I, b = e_t; the primal matrix X is the LMI's
multiplier (trace one).  Forming M costs 2 m k^3 + m^2 k^2 / 2, far less than a
general conic solver's factorisation of the full KKT system; while the
relative gap exceeds ``SINGLE_GAP`` these products run in single precision.

Owns: lmi_interior_point.  May import: design.relaxation.
"""

from dataclasses import dataclass

import numpy as np
import scipy.linalg
import scipy.linalg.blas

from .interior_point import boundary_step

__all__ = ["lmi_interior_point"]

EXTRA_STEPS = 3  # steps after convergence that tighten the primal residual (X, the caller's certificate)
WARM_SHARE = 0.01  # a warm start's weights: this share of the way from the given ones to uniform (inside the box)
# while the relative gap exceeds this, the Schur complement's products run in single precision (a fifth less time
# per step on the E relaxation's late SDPs): far from the optimum the Newton direction need not be exact (the
# residuals are exact every step, and the caller certifies from any multiplier); closer, M's conditioning needs
# double, and a single-precision M that is not positive definite is formed again in double
SINGLE_GAP = 1e-3


@dataclass(frozen=True)
class _Point:
    """An iterate: the primal X (k, k) and lam, nu; the dual y = (w, t), Z (k, k) and the slacks s."""

    x: np.ndarray
    z: np.ndarray
    y: np.ndarray
    s: np.ndarray
    lam: np.ndarray
    nu: float


@dataclass(frozen=True)
class _Residuals:
    r_p: np.ndarray  # primal: b - A(X) - G^T lam - nu 1
    r_d: np.ndarray  # dual: C - A*(y) - Z
    r_s: np.ndarray  # slacks: h - G w - s
    r_e: float  # count - sum w
    gap: float  # <X, Z> + s^T lam
    scale: float  # max(1, |t|)
    pobj: float  # primal objective


class _SmallLmi:
    """The data of the SDP, its linear maps A (X -> (<A_j, X>)_j), A* (y -> sum_j y_j A_j) and G^T."""

    def __init__(self, b0, bmat, rows, rhs, count, cuts=None, cut_rhs=None):
        self.m, self.k, _ = bmat.shape
        m, k = self.m, self.k
        self.b0, self.bmat, self.count = b0, bmat, count
        # G y <= h with y = (w, t) and G = [rows, 0; -cuts, 1; I, 0; -I, 0]: the side rows, the cuts
        # t <= cut_rhs + cuts w, and the box (kept implicit: its part of G^T D G is diagonal)
        cuts = np.zeros((0, m)) if cuts is None else cuts
        self.lin = np.zeros((rows.shape[0] + cuts.shape[0], m + 1))
        self.lin[:rows.shape[0], :m] = rows
        self.lin[rows.shape[0]:, :m] = -cuts
        self.lin[rows.shape[0]:, m] = 1.0
        self.n_cuts = cuts.shape[0]
        cut_rhs = np.zeros(0) if cut_rhs is None else cut_rhs
        self.h = np.concatenate([rhs, cut_rhs, np.ones(m), np.zeros(m)])
        self.bflat = bmat.reshape(m, k * k)
        self._tall32 = None
        self.eye = np.eye(k)
        self.ones = np.concatenate([np.ones(m), [0.0]])
        self.b = np.zeros(m + 1)
        self.b[m] = 1.0

    def tall(self, dtype):
        """The B_i stacked as one (m k, k) matrix in ``dtype`` (the single-precision copy made once)."""
        if dtype == np.float64:
            return self.bmat.reshape(self.m * self.k, self.k)
        if self._tall32 is None:
            self._tall32 = self.bmat.reshape(self.m * self.k, self.k).astype(np.float32)
        return self._tall32

    def astar(self, v):
        return -(v[:self.m] @ self.bflat).reshape(self.k, self.k) + v[self.m] * self.eye

    def a_op(self, x):
        return np.concatenate([-(self.bflat @ x.ravel()), [np.trace(x)]])

    def g_mul(self, y):
        """G y."""
        w = y[:self.m]
        return np.concatenate([self.lin @ y, w, -w])

    def gt(self, v):
        """G^T v."""
        r, m = self.lin.shape[0], self.m
        out = self.lin.T @ v[:r]
        out[:m] += v[r:r + m] - v[r + m:]
        return out

    def g_gram(self, d):
        """G^T diag(d) G, (m + 1) x (m + 1)."""
        r, m = self.lin.shape[0], self.m
        out = (self.lin.T * d[:r]) @ self.lin
        out[np.arange(m), np.arange(m)] += d[r:r + m] + d[r + m:]
        return out

    def full_multiplier(self, p):
        """blockdiag(X, multipliers of the cuts)."""
        k, n, r = self.k, self.n_cuts, self.lin.shape[0] - self.n_cuts
        out = np.zeros((k + n, k + n))
        out[:k, :k] = p.x
        out[np.arange(k, k + n), np.arange(k, k + n)] = p.lam[r:r + n]
        return out

    def start(self):
        """Uniform weights, t one below the smallest eigenvalue, X = I / k, Z a multiple of I."""
        m, k = self.m, self.k
        w0 = np.full(m, self.count / m)
        s0 = self.b0 + (w0 @ self.bflat).reshape(k, k)
        y = np.concatenate([w0, [np.linalg.eigvalsh(0.5 * (s0 + s0.T))[0] - 1.0]])
        z = self.eye * max(1.0, float(np.max(np.abs(s0))))
        s = np.maximum(self.h - self.g_mul(y), 1.0)
        return _Point(self.eye / k, z, y, s, np.ones(self.h.size), 0.0)

    def warm_start(self, w, shift):
        """From weights ``w`` (the last round's): y = (w pulled WARM_SHARE of the way to uniform, t =
        lambda_min - ``shift``), Z the dual slack there (feasible, PD), X = Z^-1 / tr Z^-1 and lam = mu / s
        with mu = 1 / tr Z^-1 (on the central path of the LMI and the linear inequalities)."""
        m, k = self.m, self.k
        w0 = (1.0 - WARM_SHARE) * np.clip(w, 0.0, 1.0) + WARM_SHARE * self.count / m
        s0 = self.b0 + (w0 @ self.bflat).reshape(k, k)
        s0 = 0.5 * (s0 + s0.T)
        y = np.concatenate([w0, [np.linalg.eigvalsh(s0)[0] - shift]])
        z = s0 - y[m] * self.eye
        zi = scipy.linalg.cho_solve(scipy.linalg.cho_factor(z, lower=True), self.eye)
        zi = 0.5 * (zi + zi.T)
        mu = 1.0 / np.trace(zi)
        s = np.maximum(self.h - self.g_mul(y), shift)
        return _Point(zi * mu, z, y, s, mu / s, 0.0)

    def residuals(self, p):
        m = self.m
        r_p = self.b - self.a_op(p.x) - self.gt(p.lam) - p.nu * self.ones
        r_d = self.b0 - self.astar(p.y) - p.z
        r_d = 0.5 * (r_d + r_d.T)
        r_s = self.h - self.g_mul(p.y) - p.s
        r_e = self.count - p.y[:m].sum()
        gap = float(np.sum(p.x * p.z) + p.s @ p.lam)
        scale = max(1.0, abs(float(p.y[m])))
        pobj = float(np.sum(self.b0 * p.x) + self.h @ p.lam + self.count * p.nu)
        return _Residuals(r_p, r_d, r_s, r_e, gap, scale, pobj)

    def converged(self, res, p, tol):
        """Relative gap, dual residuals and the sum within ``tol``; the primal residual within 1e-5."""
        norm = np.linalg.norm
        dual_ok = (norm(res.r_d) <= tol * (1.0 + norm(self.b0)) and norm(res.r_s) <= tol * (1.0 + norm(self.h))
                   and abs(res.r_e) <= tol * (1.0 + self.count))
        return dual_ok and res.gap <= tol * res.scale and abs(res.pobj - p.y[self.m]) <= 10 * tol * res.scale \
            and norm(res.r_p) <= 1e-5 * (1.0 + norm(self.b))


class _Newton:
    """The Newton system at one iterate, reduced to the Schur complement M (LinAlgError if X, Z or M
    is not positive definite), its directions and step lengths."""

    def __init__(self, lmi, p, res):
        self.lmi, self.p, self.res = lmi, p, res
        self.zc = np.linalg.cholesky(p.z)
        self.xc = np.linalg.cholesky(p.x)
        zi = scipy.linalg.cho_solve((self.zc, True), lmi.eye)
        self.zi = zi = 0.5 * (zi + zi.T)
        lzi = scipy.linalg.solve_triangular(self.zc, lmi.eye, lower=True, check_finite=False)
        xz = p.x @ zi
        self.factor = None
        if res.gap > SINGLE_GAP * res.scale:
            try:
                self.factor = scipy.linalg.cho_factor(self._schur(lzi, xz, np.float32), check_finite=False)
            except np.linalg.LinAlgError:  # too ill-conditioned for single precision
                pass
        if self.factor is None:
            self.factor = scipy.linalg.cho_factor(self._schur(lzi, xz, np.float64), check_finite=False)
        self.u1 = scipy.linalg.cho_solve(self.factor, lmi.ones, check_finite=False)

    def _schur(self, lzi, xz, dtype):
        """M, its products in ``dtype`` (the sum in double).  M_ij = tr(B_i X B_j Z^-1) = <C_i, C_j> with
        C_i = L_Z^-1 B_i L_X (X = L_X L_X^T, Z = L_Z L_Z^T): triangular products (half the flops of general
        ones) and a symmetric rank-k update (half those of a general product)."""
        lmi, p = self.lmi, self.p
        m, k = lmi.m, lmi.k
        trmm = scipy.linalg.blas.dtrmm if dtype == np.float64 else scipy.linalg.blas.strmm
        # BLAS reads a C-ordered array transposed: the (m k, k) stack [B_1; ...; B_m] is the (k, m k) Fortran
        # matrix [B_1, ..., B_m] (each B_i symmetric), which L_X^T multiplies from the left in one call (on a
        # copy), leaving the blocks B_i L_X in C order
        blocks = trmm(1.0, self.xc.astype(dtype, copy=False), lmi.tall(dtype).T, side=0, lower=1,
                      trans_a=1).T.reshape(m, k, k)
        lzi = lzi.astype(dtype, copy=False)
        for block in blocks:  # C_i^T = (B_i L_X)^T L_Z^-T in place: C_i in C order
            out = trmm(1.0, lzi, block.T, side=1, lower=1, trans_a=1, overwrite_b=1)
            if out.ctypes.data != block.ctypes.data:
                block[...] = out.T
        cmat = blocks.reshape(m, k * k)
        mmat = np.empty((m + 1, m + 1))
        mmat[:m, :m] = cmat @ cmat.T
        col = -(lmi.bflat @ xz.ravel())  # -tr(B_i X Z^-1) (B_i symmetric)
        mmat[:m, m] = mmat[m, :m] = col
        mmat[m, m] = np.trace(xz)
        mmat = 0.5 * (mmat + mmat.T)
        mmat += lmi.g_gram(p.lam / p.s)
        return mmat

    def direction(self, rc_x, rc_lin):
        """(dX, dy, dZ, ds, dlam, dnu) for the complementarity right-hand sides ``rc_x``, ``rc_lin``."""
        lmi, p, res, zi = self.lmi, self.p, self.res, self.zi
        rhs_y = res.r_p - lmi.a_op(rc_x - p.x @ res.r_d @ zi) - lmi.gt((rc_lin - p.lam * res.r_s) / p.s)
        u0 = scipy.linalg.cho_solve(self.factor, rhs_y, check_finite=False)
        dnu = (lmi.ones @ u0 - res.r_e) / (lmi.ones @ self.u1)
        dy = u0 - dnu * self.u1
        dz = res.r_d - lmi.astar(dy)
        dx = rc_x - p.x @ dz @ zi
        ds = res.r_s - lmi.g_mul(dy)
        return 0.5 * (dx + dx.T), dy, dz, ds, (rc_lin - p.lam * ds) / p.s, dnu

    def max_steps(self, dx, dz, ds, dlam):
        """Largest primal and dual steps (at most 1) that keep X, lam and Z, s positive."""
        steps = []
        for chol, dmat, v, dv in ((self.xc, dx, self.p.lam, dlam), (self.zc, dz, self.p.s, ds)):
            li = scipy.linalg.solve_triangular(chol, self.lmi.eye, lower=True, check_finite=False)
            low = np.linalg.eigvalsh(li @ dmat @ li.T)[0]
            steps.append(boundary_step(v, dv, 1.0 if low >= 0 else min(1.0, -1.0 / low)))
        return steps

    def predictor_corrector(self):
        """The next iterate: Mehrotra's predictor (affine scaling) and corrector, 98 % of the way to
        the boundary."""
        p, zi = self.p, self.zi
        mu = self.res.gap / (self.lmi.k + self.lmi.h.size)
        dx, dy, dz, ds, dlam, dnu = self.direction(-p.x, -p.lam * p.s)  # predictor
        ap, ad = self.max_steps(dx, dz, ds, dlam)
        gap_aff = float(np.sum((p.x + ap * dx) * (p.z + ad * dz)) + (p.s + ad * ds) @ (p.lam + ap * dlam))
        sigma = (max(gap_aff, 0.0) / self.res.gap) ** 3
        dx, dy, dz, ds, dlam, dnu = self.direction(sigma * mu * zi - p.x - dx @ dz @ zi,  # corrector
                                                   sigma * mu - p.lam * p.s - dlam * ds)
        ap, ad = self.max_steps(dx, dz, ds, dlam)
        ap, ad = 0.98 * ap, 0.98 * ad
        x = p.x + ap * dx
        z = p.z + ad * dz
        return _Point(0.5 * (x + x.T), 0.5 * (z + z.T), p.y + ad * dy, p.s + ad * ds, p.lam + ap * dlam,
                      p.nu + ap * dnu)


def lmi_interior_point(b0, bmat, rows, rhs, count, *, cuts=None, cut_rhs=None, tol=1e-9, max_iter=100,
                       start=None):
    """max t s.t. B0 + sum_i w_i B_i - t I >= 0, t <= cut_rhs + cuts w, 0 <= w <= 1, rows w <= rhs,
    sum w = count (module docstring), the B_i (``bmat``, m x k x k) symmetric.

    The cuts are the LMI's 1 x 1 diagonal blocks written as linear rows (a
    rank-one direction u of the caller's certificate: t <= u^T Q(w) u).
    Returns (t, w, X, nu, status, iterations, row multipliers), X the
    multiplier of the block-diagonal LMI (the k x k block, then the cuts'
    multipliers on the diagonal; trace one), nu the multiplier of sum w =
    count, the row multipliers those of ``rows`` (>= 0): at the optimum
    <X, B_i> = nu + sum_r mult_r rows_ri for 0 < w_i < 1.  ``status``
    is "optimal" when the relative gap, the dual residuals and the sum
    constraint are within ``tol`` and the primal residual (the multiplier
    equations, which only affect the quality of X as a certificate, checked
    independently by the caller) within 1e-5.

    ``start``: (weights, shift) to start from, e.g. the last solution of a
    sequence of such SDPs: the iterate is put on the central path at the
    dual point t = lambda_min - shift of those weights (about a third fewer
    steps in the E relaxation's rounds); None starts from uniform weights.
    """
    lmi = _SmallLmi(b0, bmat, rows, rhs, count, cuts, cut_rhs)
    m = lmi.m
    p = lmi.start()
    if start is not None:
        try:
            p = lmi.warm_start(*start)
        except np.linalg.LinAlgError:  # Z not numerically PD at that shift: the cold start
            pass
    best, extra = None, 0
    for it in range(1, max_iter + 1):
        res = lmi.residuals(p)
        if lmi.converged(res, p, tol):
            best = (float(p.y[m]), p.y[:m].copy(), lmi.full_multiplier(p), float(p.nu), p.lam[:rows.shape[0]].copy())
            extra += 1  # a few more steps to tighten the primal residual
            if extra > EXTRA_STEPS or res.gap <= 0.1 * tol * res.scale and np.linalg.norm(res.r_p) <= tol:
                break
        try:
            newton = _Newton(lmi, p, res)
        except np.linalg.LinAlgError:
            break
        p = newton.predictor_corrector()
    if best is None:
        status = "max iterations" if it == max_iter else "numerical problems"
        return float(p.y[m]), p.y[:m], lmi.full_multiplier(p), float(p.nu), status, it, p.lam[:rows.shape[0]]
    return (*best[:4], "optimal", it, best[4])
