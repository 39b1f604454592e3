"""Independent finite-element reference for the tests (shares no code with sensorplan).

Euler-Bernoulli beam, cubic Hermite elements, DOFs (w, theta) per node with
w downward and theta = dw/dx.  Nodes are placed at every EI edge, support,
sensor and axle, so nodal displacements and rotations are exact for point
loads and piecewise-constant EI (the Hermite interpolants contain the exact
homogeneous solution of EI w'''' = 0 on each element).
Springs are added to the diagonal; rigid restraints are eliminated.
"""

import math

import numpy as np


def _element_stiffness(ei, h):
    # Standard Hermite beam element (e.g. Przemieniecki, Theory of Matrix
    # Structural Analysis, 1968, eq. 5.111), DOFs (w1, t1, w2, t2).
    ei = np.longdouble(ei)
    h = np.longdouble(h)
    return ei / h**3 * np.array([
        [12.0, 6 * h, -12.0, 6 * h],
        [6 * h, 4 * h * h, -6 * h, 2 * h * h],
        [-12.0, -6 * h, 12.0, -6 * h],
        [6 * h, 2 * h * h, -6 * h, 4 * h * h],
    ], dtype=np.longdouble)


def _key(x):
    # One rounding for node positions and their look-ups.
    out = np.round(np.asarray(x, dtype=float), 12)
    return float(out) if out.ndim == 0 else out


def _refined_solve(k, f):
    # Soft springs next to very short, stiff elements make K ill-conditioned;
    # so K is assembled in extended precision (longdouble) and the solution is
    # refined iteratively with residuals in extended precision, which restores
    # the accuracy the comparison needs.
    # restores the accuracy the comparison needs.
    k_ext = k.astype(np.longdouble)
    f_ext = f.astype(np.longdouble)
    k64 = k_ext.astype(float)
    x = np.linalg.solve(k64, f_ext.astype(float)).astype(np.longdouble)
    for _ in range(6):
        r = f_ext - k_ext @ x
        x = x + np.linalg.solve(k64, r.astype(float)).astype(np.longdouble)
    return x.astype(float)


def fe_response(spans, ei_edges, ei_values, rot_springs, vert_springs, loads, sensors):
    """Readings of ``sensors`` under point ``loads``.

    Parameters
    ----------
    spans : list of float
    ei_edges : increasing array of EI edges (from 0 to the length)
    ei_values : EI on each interval of ``ei_edges``
    rot_springs, vert_springs : per support, inf = rigid / clamped, 0 = free
    loads : list of (position, downward force)
    sensors : list of (position, "rotation" | "deflection")
    """
    supports = np.concatenate([[0.0], np.cumsum(spans)])
    length = supports[-1]
    points = list(ei_edges) + list(supports) + [p for p, _ in loads] + [p for p, _ in sensors]
    nodes = np.unique(_key(np.array(points, dtype=float)))
    n = nodes.size
    k = np.zeros((2 * n, 2 * n), dtype=np.longdouble)
    for e in range(n - 1):
        h = np.longdouble(nodes[e + 1]) - np.longdouble(nodes[e])
        mid = 0.5 * (nodes[e] + nodes[e + 1])
        idx = min(np.searchsorted(ei_edges, mid, side="right") - 1, len(ei_values) - 1)
        dofs = [2 * e, 2 * e + 1, 2 * e + 2, 2 * e + 3]
        k[np.ix_(dofs, dofs)] += _element_stiffness(ei_values[idx], h)
    f = np.zeros(2 * n)
    node_of = {float(x): i for i, x in enumerate(nodes)}
    for p, force in loads:
        f[2 * node_of[_key(p)]] += force
    fixed = []
    for x, kr, kv in zip(supports, rot_springs, vert_springs):
        i = node_of[_key(x)]
        if math.isinf(kv):
            fixed.append(2 * i)
        else:
            k[2 * i, 2 * i] += kv
        if math.isinf(kr):
            fixed.append(2 * i + 1)
        else:
            k[2 * i + 1, 2 * i + 1] += kr
    free = np.setdiff1d(np.arange(2 * n), fixed)
    u = np.zeros(2 * n)
    u[free] = _refined_solve(k[np.ix_(free, free)], f[free])
    out = []
    for p, kind in sensors:
        i = node_of[_key(p)]
        out.append(u[2 * i + 1] if kind == "rotation" else u[2 * i])
    return np.array(out)
