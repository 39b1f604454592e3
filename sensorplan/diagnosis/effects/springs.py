"""Support springs: a rotational or vertical spring at every support, and the case's own elastic springs.

Owns: :class:`SupportRotationalSpring`, :class:`VerticalSupportSpring`, :class:`CaseSprings`.
May import: the effect protocol, the column blocks, numpy.
"""

import math
from dataclasses import replace

import numpy as np

from ..joint.columns import Outer
from .base import EffectBlock, StructuralEffect
from .findings import Z95, finding, informed

__all__ = ["CaseSprings", "SupportRotationalSpring", "VerticalSupportSpring"]

UNIT = {"rotational": "N·m/rad", "vertical": "N/m"}


def _span_reference(ctx, support):
    """(median EI of the case [N m^2], the length of the span(s) next to ``support`` [m])."""
    bridge = ctx.case.bridge
    xs = bridge.support_positions
    spans = np.array(bridge.spans)
    if support == 0:
        length = spans[0]
    elif support == len(xs) - 1:
        length = spans[-1]
    else:
        length = 0.5 * (spans[support - 1] + spans[support])
    ei = float(np.median(ctx.case.ei))
    return ei, float(length)


def _fixity_prior(ctx, stiffness, reference, low, high, std=2.5):
    """Prior mean and std of log k from the fixity f = k / (k + reference), clipped to [low, high].

    log k is flat in the data near f = 0 or 1 (a pin, a clamp, a rigid
    support), so the prior starts where the data can act on it.
    """
    mean = []
    for i, k in enumerate(stiffness):
        ref = reference(*_span_reference(ctx, i))
        f = float(np.clip(k / (k + ref) if np.isfinite(k) else 1.0, low, high))
        mean.append(math.log(ref * f / (1.0 - f)))
    return np.array(mean), np.full(len(mean), std)


def _spring_finding(kind, support, x, mean, std):
    """The finding of one spring's log stiffness (MAP ``mean``, std ``std``) at support ``support`` (x [m])."""
    return finding(f"{kind} spring at support {support} (x = {x:.1f} m)", math.exp(mean), math.exp(mean - Z95 * std),
                   math.exp(mean + Z95 * std), UNIT[kind], ".2e")


class _SupportSprings(StructuralEffect):
    """A spring of kind ``KIND`` at every support; the fixity prior of :func:`_fixity_prior`."""

    KIND = ""
    in_case = True

    def _replaced(self, bridge, values):
        """``bridge`` with the springs of this kind set to ``values``."""
        if self.KIND == "rotational":
            return type(bridge)(bridge.spans, tuple(values), bridge.vertical_springs)
        return type(bridge)(bridge.spans, bridge.rotational_springs, tuple(values))

    def _springs(self, bridge):
        return bridge.rotational_springs if self.KIND == "rotational" else bridge.vertical_springs

    def apply(self, block, state, phi):
        state.bridge = self._replaced(state.bridge, np.exp(phi))

    def apply_corrected(self, block, state, phi, std, case):
        """As :meth:`apply`; supports the data did not inform (posterior = prior) keep the case's value."""
        self.apply(block, state, phi)
        springs, source = list(self._springs(state.bridge)), self._springs(case.bridge)
        for i in np.flatnonzero(~informed(phi, std, block.mean, block.std)):
            springs[i] = source[i]
        state.bridge = self._replaced(state.bridge, springs)

    def jacobian(self, block, ctx, state, phi, c, y):
        """dy/dlog k of the springs at every support (S, N, supports); zero where a support is rigid."""
        lines = ctx.lines(state, c)
        n = state.bridge.support_positions.size
        pairs = [(col, int(name.partition("_")[2])) for col, name in enumerate(state.bridge.spring_names)
                 if name.partition("_")[0] == self.KIND]
        if not pairs:
            return np.zeros(lines.predictions.shape + (n,))
        cols, supports = zip(*pairs)
        jac = lines.spring_log_columns(ctx.load_factor(c), cols)
        if list(supports) == list(range(n)):
            return jac
        sensors, loads = (np.zeros((len(part), n)) for part in (jac.sensors, jac.loads))
        sensors[:, list(supports)], loads[:, list(supports)] = jac.sensors, jac.loads
        return Outer(sensors, loads)

    def describe(self, block, ctx, mean, std):
        ok = informed(mean, std, block.mean, block.std)
        xs = ctx.case.bridge.support_positions
        return [_spring_finding(self.KIND, i, xs[i], mean[i], std[i]) for i in range(block.n_params) if ok[i]]


class SupportRotationalSpring(_SupportSprings):
    """A rotational spring at every support (pins gain a restraint, clamps lose some)."""

    name = "support_rotational_spring"
    KIND = "rotational"
    frees = ("rotational",)

    def configure(self, ctx):
        # fixity f = k / (k + 4 EI / L): a pin is taken as f = 0.05, a clamp as 0.95
        n = ctx.case.bridge.support_positions.size
        mean, std = _fixity_prior(ctx, ctx.case.bridge.rotational_springs,
                                  lambda ei, length: 4.0 * ei / length, 0.05, 0.95)
        return EffectBlock(self, tuple(f"log_k_rot_{i}" for i in range(n)), mean, std)


class VerticalSupportSpring(_SupportSprings):
    """A vertical spring at every support (rigid supports may settle)."""

    name = "vertical_support_spring"
    KIND = "vertical"
    frees = ("vertical",)

    def configure(self, ctx):
        # f = k / (k + 48 EI / L^3), support against mid-span stiffness: rigid is taken as f = 0.98
        n = ctx.case.bridge.support_positions.size
        mean, std = _fixity_prior(ctx, ctx.case.bridge.vertical_springs,
                                  lambda ei, length: 48.0 * ei / length**3, 0.02, 0.98)
        return EffectBlock(self, tuple(f"log_k_vert_{i}" for i in range(n)), mean, std)


class CaseSprings(StructuralEffect):
    """The elastic springs of the case, estimated as ``invert`` does (a nuisance of the base model).

    Springs of the kinds in ``freed`` are left to the effect that frees
    them.  Its block's ``detail``: the (support, kind) of every spring it
    estimates.
    """

    name = "case_springs"
    in_case = True

    def __init__(self, freed=()):
        self.freed = frozenset(freed)

    def configure(self, ctx):
        bridge = ctx.case.bridge
        pairs = tuple((i, kind) for i, kind in bridge.spring_parameters if kind not in self.freed)
        mean = np.array([np.log(bridge.rotational_springs[i] if kind == "rotational" else bridge.vertical_springs[i])
                         for i, kind in pairs])
        return EffectBlock(self, tuple(f"log_k_{kind}_{i}" for i, kind in pairs), mean,
                           np.full(len(pairs), ctx.prior.spring_std), detail=pairs)

    def apply(self, block, state, phi):
        b = state.bridge
        rot, vert = list(b.rotational_springs), list(b.vertical_springs)
        for (i, kind), v in zip(block.detail, np.exp(phi)):
            (rot if kind == "rotational" else vert)[i] = float(v)
        state.bridge = type(b)(b.spans, tuple(rot), tuple(vert))

    def jacobian(self, block, ctx, state, phi, c, y):
        lines = ctx.lines(state, c)
        names = list(state.bridge.spring_names)
        return lines.spring_log_columns(ctx.load_factor(c), [names.index(f"{kind}_{i}") for i, kind in block.detail])

    def describe(self, block, ctx, mean, std):
        """Every spring's value, with the case's value and whether the 95 % interval excludes it."""
        xs = ctx.case.bridge.support_positions
        out = []
        for j, (i, kind) in enumerate(block.detail):
            f = _spring_finding(kind, i, xs[i], mean[j], std[j])
            nominal = math.exp(block.mean[j])
            differs = bool(not f.low <= nominal <= f.high)
            note = f" (case: {nominal:.2e} {f.unit}{'; differs' if differs else ''})"
            out.append(replace(f, text=f.text + note, case_value=nominal, differs=differs))
        return out
