"""Warnings about the state of a run's steps (the run goes on).

- the largest elastic strain (summary.csv ``elastic_strain_max``) first enters a higher band of
  ``STRAIN_BANDS``: once per band, so a run that keeps stretching warns again, and a resumed run
  warns only for a band its earlier steps had not reached;
- the applied loads' net x1 force passes ``WARN_LOAD_IMBALANCE`` (1%) of the largest edge force
  (the pinned point carries it; above ``MAX_LOAD_IMBALANCE`` the run stops: runner.timeloop);
- a connected non-elliptic set larger than one cell appears (the material law loses strong
  ellipticity there: plantgrowth.models.stability), and again each time the non-elliptic area
  enters a higher power of two of the tissue's (doubling bands, like the strain bands: a resumed
  run warns as the whole run would); with ``numerics.on_instability = "stop"``, the default, the
  run stops at the first such set instead (runner.timeloop);
- singular points (non-elliptic sets within one cell: plantgrowth.models.nonelliptic_sets) are
  reported once per place (:meth:`StepWarnings.singular_points`), never a stop;
- the clamp M is active (some ``|G_ij| = M``) on more than ``MAX_CLAMPED_FRACTION`` (10%) of the
  tissue, area-weighted (macro: fine cells, micro: biological cells by their reference areas);
- one step grows the tissue's area by more than ``MAX_STEP_GROWTH`` (:meth:`StepWarnings.growth`:
  usually eta in the wrong units, which the warning names for the growth law).

The clamp, the loads and the step growth: each at most once per run.
"""

from __future__ import annotations

import math
from bisect import bisect_right

from plantgrowth.models.elastic_strain import StrainPeak
from plantgrowth.models.nonelliptic_sets import NonellipticSet
from plantgrowth.models.stability import Ellipticity
from plantgrowth.models.step import StepResult

STRAIN_BANDS = (0.2, 0.5, 1.0)
"""Lower ends of the elastic-strain bands that warn. Measured (scripts/studies/strain_bands.py,
draft preset, benchmarks/results/strain_bands.json): the shipped examples that stay in the model
reach 0.016 (reference) to 0.12 (gradient_w_stress), 0.10 (the pull of docs/usage.md, at t = 0),
0.11 (biology/anisotropic_pregrowth), 0.17 (biology/stiff_band); up to 0.2 linear and finite
kinematics agree on area and mean tr G to 0.6%. Above it they part: examples/soft_disc at t = 23
has 0.224 (linear) against 0.248 (finite), and its finite run fails at t = 24; soft_patch 0.25
against 0.39 at t = 39. So 20% is where the linear model stops being trustworthy (the old 5%
warned on the pull example and most gradients), 50% and 100% where the wall law itself is far
outside its range (soft_patch's linear run reaches 0.52 at t = 52 and 1.05 at t = 60)."""
MAX_STEP_GROWTH = 1.5
"""Largest plausible growth of the tissue's area in one step, ``exp(growth_rate_area dt)`` (what
the step's advance does to the reference-area mean of det Fg: known before the step is taken).
Measured (scripts/studies/area_growth.py: the 47 shipped scenes and hard cases, draft meshes,
each scene's own dt; benchmarks/results/area_growth.json): the examples, biology, shape and
gradient scenes reach at most 1.020 per step (gradient_l_stress), the hard cases 1.061 and
1.128 (thin_wall_w0.01, w0.005: walls 5 and 10 times thinner) and 1.057 (long_run, dt = 5).
1.5 is 3.4 times the log of the largest (ln 1.5 = 0.41 against 0.12) and well below the
clamp's bound exp(2 M dt) = 7.4 (M = 1, dt = 1), which a run with eta in the wrong units
reaches at once (E = 300, P1 = 0.3 in MPa at eta = 1: 54 times the area in 2 steps)."""
MAX_CLAMPED_FRACTION = 0.10
WARN_LOAD_IMBALANCE = 0.01
MAX_LOAD_IMBALANCE = 0.10
"""The loads' net x1 force over the largest edge force: a warning above 1%, a stop above 10%
(issue 20: the drift of tractions balanced on the reference edges measured 4.6% at t = 0 with
finite kinematics and 7.1% at t = 10 with linear, on a 3 x 1.5 tissue with E 0.5 -> 2)."""


class StepWarnings:
    """Warnings about the state of a run's steps: the strain once per band, the others once
    per run.

    Args:
        kinematics: the scene's kinematics ("linear" or "finite": what the strain warnings
            advise).
        strain_reached: the largest elastic strain of the steps before (a resumed run's kept
            summary rows; 0 for a new run): its band does not warn again.
        nonelliptic_reached: likewise the largest ``nonelliptic_area_fraction`` before.
    """

    def __init__(
        self, kinematics: str = "linear", strain_reached: float = 0.0,
        nonelliptic_reached: float = 0.0,
    ) -> None:  # fmt: skip
        self.given: set[str] = set()
        self.kinematics = kinematics
        self.strain_band = bisect_right(STRAIN_BANDS, strain_reached)
        self.nonelliptic_band = doubling_band(nonelliptic_reached)
        self.singular_places: list[NonellipticSet] = []

    def check(self, step: int, t: float, result: StepResult) -> list[str]:
        """New warnings for this step's result."""
        out = []
        clamped = result.clamped_fraction
        if result.elastic_strain is not None:
            out += self._strain(step, t, result.elastic_strain)
        if clamped is not None and clamped > MAX_CLAMPED_FRACTION:
            out += self._once(
                "clamp",
                f"step {step}, t = {t:g}: the clamp growth.clamp = M is active on {clamped:.0%} "
                f"of the tissue (more than {MAX_CLAMPED_FRACTION:.0%}, area-weighted): the "
                "growth rate there is M, not the growth law's (raise M or lower eta)",
            )
        balance = result.load_balance
        if balance is not None and balance.imbalance > WARN_LOAD_IMBALANCE:
            out += self._once("loads", f"step {step}, t = {t:g}: {balance.describe()}")
        if result.ellipticity is not None:
            out += self._nonelliptic(step, t, result.ellipticity)
        return out

    def _nonelliptic(self, step: int, t: float, lost: Ellipticity) -> list[str]:
        """The warning of a non-elliptic area larger than a cell that first appears or enters a
        higher doubling band (none otherwise)."""
        band = doubling_band(lost.nonelliptic_area_fraction)
        if band is None or (self.nonelliptic_band is not None and band <= self.nonelliptic_band):
            return []
        grown = "appeared" if self.nonelliptic_band is None else "at least doubled"
        self.nonelliptic_band = band
        return [
            f"step {step}, t = {t:g}: a non-elliptic area larger than a cell {grown} "
            f"({lost.nonelliptic_area_fraction:.3g} of the tissue): {lost.describe(t)}"
        ]

    def singular_points(self, step: int, t: float, lost: Ellipticity | None) -> list[str]:
        """Reports of the singular points (non-elliptic sets within one cell) at places not
        reported before: a place is new unless it lies within a cell's diameter of one
        reported."""
        out = []
        for point in () if lost is None else lost.singular:
            if any(_near(point, seen) for seen in self.singular_places):
                continue
            self.singular_places.append(point)
            out.append(
                f"step {step}, t = {t:g}: a singular point at {point.where()}: a non-elliptic "
                f"set of {point.cells:.2g} of a cell's area (smallest acoustic eigenvalue "
                f"{point.smallest:.3g} times the shear modulus), beneath the model's resolution "
                "of one cell (a corner of a held edge, a re-entrant corner, a sharp jump of a "
                "parameter): the fields there are not resolved; the run goes on (reported once "
                "per place; summary.csv column singular_points)"
            )
        return out

    def growth(self, step: int, t: float, rate: float, dt: float, law: str) -> list[str]:
        """The warning (once per run) of a step that grows the tissue's area by more than
        MAX_STEP_GROWTH: the mean areal growth rate ``rate`` (summary.csv's growth_rate_area)
        over ``dt``, under the growth ``law``."""
        factor = math.exp(rate * dt)
        if not factor > MAX_STEP_GROWTH:
            return []
        return self._once(
            "growth",
            f"step {step}, t = {t:g}: the mean growth rate tr G = {rate:.3g} grows the tissue's "
            f"area by a factor {factor:.3g} in one step of dt = {dt:g} (more than "
            f"{MAX_STEP_GROWTH:g}): {eta_units(law)}",
        )

    def _strain(self, step: int, t: float, peak: StrainPeak) -> list[str]:
        """The warning of a higher strain band than any reached before (none otherwise)."""
        band = bisect_right(STRAIN_BANDS, peak.value)
        if band <= self.strain_band:
            return []
        self.strain_band = band
        x1, x2 = peak.place
        where = (
            f"step {step}, t = {t:g}: the largest elastic strain reached {peak.value:.3g} "
            f"(the tissue stretched or compressed elastically by {peak.value:.0%} beyond its grown "
            "shape) "
            f"at x1 = {x1:.4g}, x2 = {x2:.4g} (reference position), above "
            f"{STRAIN_BANDS[band - 1]:.0%}: "
        )
        return [where + strain_advice(band, self.kinematics)]

    def _once(self, kind: str, text: str) -> list[str]:
        if kind in self.given:
            return []
        self.given.add(kind)
        return [text]


def doubling_band(fraction: float) -> int | None:
    """``floor(log2(fraction))`` (None for 0): the non-elliptic area warns again each time it
    enters a higher band, i.e. at least doubles, the same in a resumed run as in a whole one."""
    return math.floor(math.log2(fraction)) if fraction > 0.0 else None


def _near(a: NonellipticSet, b: NonellipticSet) -> bool:
    """True if two sets lie within a cell's diameter, ``sqrt(Jg |Y|)``, of each other."""
    reach = math.sqrt(max(a.cell_area, b.cell_area))
    return math.dist(a.place, b.place) <= reach


def strain_advice(band: int, kinematics: str) -> str:
    """What a strain band (1, 2, ...: above STRAIN_BANDS[band - 1]) means and what to do."""
    if band == 1 and kinematics == "linear":
        return (
            "linear kinematics reads strains and rotations this large only approximately (its "
            "growth rates differ from the exact ones by about the strain squared); run the scene "
            'with kinematics = "finite" to check the results'
        )
    if band == 1:
        return (
            "the kinematics are exact, but the wall law is linear in the strain (fitted to small "
            "strains), so the walls' stiffness here is only approximate"
        )
    law = (
        " even with finite kinematics: check"
        if kinematics == "finite"
        else ': run with kinematics = "finite", and check'
    )
    return (
        "far beyond the small strains the wall law is made for, so the results are qualitative "
        f"only{law} turgor P1, loads, E and Fg0 (too soft walls or too strong loads?) and growth "
        'contrasts (eta, tau: a smaller time.dt or time.integrator = "adaptive" follows fast '
        "growth more closely)"
    )


def eta_units(law: str) -> str:
    """What the units of growth.eta are under a growth law, and what to do when it is too large."""
    if law == "stress":
        return (
            "are growth.eta's units right? Under the stress law eta is a rate per unit stress per "
            "unit time (G = eta [sigma / phi_w - tau]_+), so eta = 1 suits the non-dimensional "
            "E = 1, P1 = 0.001; with E and P1 in MPa (E = 300, P1 = 0.3) it must scale as 1/E "
            "(eta / E: 1/300 there), or give E and P1 in units of E (docs/model.md section 11); "
            'a smaller time.dt (or time.integrator = "adaptive") follows fast growth more closely'
        )
    return (
        "is growth.eta too large? Under the strain law eta is a rate per unit strain per unit time "
        "(G = eta [eps / phi_w - tau]_+), independent of the units of E and P1: lower eta (or "
        "time.dt, to follow fast growth more closely)"
    )
