"""Settings of the global search over SO(3) (:func:`o3d_spectral.registration_spectral_global`),
in the style of Open3D's ``*Option`` classes (:mod:`o3d_spectral.options`): a frozen
dataclass with defaults and a readable ``repr``, every field checked on construction.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..common.checks import check_bool, check_choice, check_int
from ..options import SpectralRegistrationOption

__all__ = ["GlobalSearchOption", "ROTATIONS"]

#: The values of :attr:`GlobalSearchOption.rotations` (the command line's ``--rotations``
#: lists them again, to keep its start-up free of the search's imports).
ROTATIONS = ("auto", "adaptive", "dense", "escalating")


@dataclass(frozen=True)
class GlobalSearchOption:
    """The search over all of SO(3) (:func:`o3d_spectral.registration_spectral_global`).

    The EGIs' rotation correlation is sampled on a grid of ZYZ Euler angles; its peaks
    (and, between two scans, the shells' and the sweep's candidates) are placed by phase
    correlation and scored by its peak height; the best is confirmed by a short ICP
    (``confirm``) or else the ``climbs`` best are climbed by the law and the best-scoring
    iterate is returned (``docs/method.md``). The defaults are the measured choice
    (``docs/design-notes.md``): lower ``hypotheses``, ``climbs`` or ``sweep_rotations``
    only to trade success for time, and set ``workers`` to share the machine.

    Attributes
    ----------
    hypotheses : int, default 32
        Peaks of the rotation correlation placed, >= 2.
    climbs : int, default 4
        Placed hypotheses climbed by the law, 1 to ``hypotheses``.
    hypothesis_iterations : int, default 12
        Iterations of the law from each climbed hypothesis before they are ranked again,
        >= 1.
    egi_focus : bool, default True
        In a fixed cloud larger than the moving one (a scene): also correlate the moving
        EGI with the fixed cloud's normals around the places the first hypotheses put
        it, add those correlations' peaks, and let each climb match only the fixed
        normals near its own points. No effect when the clouds are about one size.
    focus_places : int, default 3
        With ``egi_focus``: the number of places the EGI is focused on, >= 1, the best
        distinct places (over the moving cloud's radius apart) of the first hypotheses.
    scene_hypotheses : int, default 16
        In a scene (a fixed cloud over 1.5 times the moving one's radius) searched with
        ``egi_focus``: the whole EGI's highest peaks placed over the whole scene to find
        the focus places, >= 1. Each costs a phase correlation on the whole scene's grid.
    search_visibility : bool, default True
        Against a single view (``CloudOption.target_viewpoint``): correlate the fixed
        EGI with the moving one as the sensor would see it at each rotation (weighted by
        the cosine of incidence, normalised over its visible part). False: with the
        whole moving EGI.
    search_samples : int or None, default None
        Samples of each Euler angle in the rotation grid, >= ``2 * bandwidth - 1``;
        None: ``4 * bandwidth`` (steps of 180 / (2B) degrees in alpha and gamma). Memory
        grows with its cube (:meth:`check_memory`).
    shell_hypotheses : int, default 32
        Between two single views (two scans): peaks of the correlation of the voxel
        grids' spectra on spherical shells tried besides the EGI's, >= 0; 0 tries none.
    sweep_rotations : int, default 1000
        Between two single views: rotations spread evenly over SO(3), >= 0 (those that
        keep the two sensors within 110 degrees are tried), placed on a coarse grid, the
        best 16 kept as more candidates; 0 tries none.
    rotations : {"auto", "adaptive", "dense", "escalating"}, default "auto"
        How SO(3) is swept where the first candidates are not confirmed. ``"auto"``:
        ``"dense"`` where the correlations run on a GPU (the call's ``device``),
        ``"escalating"`` on the CPU (:meth:`sweep_on`). ``"adaptive"``:
        between two single views, ``sweep_rotations`` rotations ranked on a coarse grid;
        in no other case. ``"dense"``: ``dense_rotations`` even rotations ranked coarse
        to fine up to the voxel's own grid and the best refined there
        (:mod:`o3d_spectral.search.dense`), placed anywhere in the fixed cloud: more
        calls right where the clouds share little of their normals (scans far apart)
        and where a scene's other surfaces hide the object's in the EGI (clutter), at
        seconds a call on a few cores. ``"escalating"``: ``"adaptive"`` first; where its
        pose may be wrong (its calibrated confidence under one half), the dense search
        too, and the more confident of the two results returned: the dense search's
        successes at about the adaptive search's time, since calls whose pose is not in
        doubt pay nothing more. The confidence of the more confident of two is
        not calibrated for that choice: on held-out occluded views it returned three
        wrong poses at 0.73-0.86 where the adaptive search's poses (two wrong, one
        right) were doubted, in the cluttered suite six wrong ones at 0.58-1.0 (four
        of them fitting the observed points as well as the truth) beside 25 more right
        (``docs/design-notes.md``).
    dense_rotations : int, default 4608
        With ``rotations="dense"``: the even rotations sampled, >= 1 (4608: every
        rotation within about 13 degrees of one, 7 at the median; the peak the search
        ranks by falls to half about 10 degrees from the truth). Time grows with it.
    confirm : bool, default True
        Polish the best placed hypothesis by a short point-to-plane ICP and, where its
        fit shows it clearly right, return it without the climbs (not in a scene), so
        easy cases end early. False: always climb.
    peak_ascent : bool, default True
        Between two single views: turn the best pose to where the phase correlation's
        peak is highest before the polish (the law's EGI term sees only what each
        sensor saw and leaves such poses degrees off). Not applied to a model against a
        view or a scene.
    coarse_placements : int, default 16
        Between two single views: the candidates (about 80) are first placed on a grid
        of twice the voxel (an eighth of the FFT) and only this many, the highest, are
        placed at full resolution, >= 0; 0 places every one at full resolution. Not
        applied to a model against a view or a scene.
    second_opinions : int, default 0
        Where the pose the search returns may be wrong (its calibrated confidence under
        one half, after the climbs), up to this many of the other climbs' poses, distinct
        from it, are climbed on to convergence, polished and measured, and the most
        confident result is returned, >= 0; 0 never. Each costs about a local
        registration; calls whose pose is not in doubt pay nothing. More calls end right
        (3: 4 more of 146 bench calls), but the confidence of a result chosen as the most
        confident of several is no longer calibrated: wrong poses so chosen are warned
        less often (the warning's recall 0.91 -> 0.78 on the calibration's held-back
        calls), hence off by default.
    turns : int, default 12
        Where the returned pose may be wrong (its calibrated confidence under one half)
        and the motion its inliers resist least is a turn they barely hold (two views of
        a mug, whose body fits at any turn about its axis and whose handle then misses),
        the pose is turned about that axis in this many even steps, the turns polished
        briefly and the best two polished and measured whole; the most confident result
        whose inliers hold every motion is returned, >= 0; 0 never. Not in a scene (a
        turned object finds other surfaces to fit there). Calls whose pose is not in
        doubt pay nothing; the others 0.03-0.6 s on the bench.
    workers : int or None, default None
        Threads the independent parts of the search run on, >= 1 (placements, the
        sweep's batches, the confirmation's polishes, the climbs, the ascent's starts);
        None: every core, as Open3D's RANSAC (at most ``OMP_NUM_THREADS`` when set). The
        result is the same to the bit whatever the count.
    """

    hypotheses: int = 32
    climbs: int = 4
    hypothesis_iterations: int = 12
    egi_focus: bool = True
    focus_places: int = 3
    scene_hypotheses: int = 16
    search_visibility: bool = True
    search_samples: int | None = None
    shell_hypotheses: int = 32
    sweep_rotations: int = 1000
    rotations: str = "auto"
    dense_rotations: int = 4608
    confirm: bool = True
    peak_ascent: bool = True
    coarse_placements: int = 16
    second_opinions: int = 0
    turns: int = 12
    workers: int | None = None

    def __post_init__(self) -> None:
        check_int("hypotheses", self.hypotheses, low=2)
        check_int("shell_hypotheses", self.shell_hypotheses, low=0)
        check_int("coarse_placements", self.coarse_placements, low=0)
        check_int("sweep_rotations", self.sweep_rotations, low=0)
        check_choice("rotations", self.rotations, ROTATIONS)
        check_int("dense_rotations", self.dense_rotations, low=1)
        check_int("second_opinions", self.second_opinions, low=0)
        check_int("turns", self.turns, low=0)
        check_int("climbs", self.climbs, low=1, high=self.hypotheses, high_name="hypotheses")
        for name in ("hypothesis_iterations", "focus_places", "scene_hypotheses"):
            check_int(name, getattr(self, name), low=1)
        for name in ("egi_focus", "search_visibility", "confirm", "peak_ascent"):
            check_bool(name, getattr(self, name))
        check_int("search_samples", self.search_samples, low=3, optional=True)
        check_int("workers", self.workers, low=1, optional=True)

    def sweep_on(self, gpu: bool) -> str:
        """The sweep of SO(3) on a device: ``rotations``, ``"auto"`` resolved (``"dense"``
        on a GPU, where thousands of correlations take milliseconds; ``"escalating"`` on
        the CPU, where they take seconds and are spent only on doubtful poses)."""
        if self.rotations != "auto":
            return self.rotations
        return "dense" if gpu else "escalating"

    def check_memory(self, option: SpectralRegistrationOption) -> None:
        """``ValueError`` when the SO(3) correlation grid (complex, ``samples^3``, three
        transforms against a single view) would exceed ``option.max_grid_memory``."""
        samples = self.samples(option.bandwidth)
        need = 3.0 * 16.0 * float(samples) ** 3
        if need > option.max_grid_memory:
            raise ValueError(
                f"the global search's SO(3) grid of {samples}^3 rotations needs about "
                f"{need / 2**20:.0f} MiB, over max_grid_memory={option.max_grid_memory:.3g} "
                f"bytes: lower GlobalSearchOption.search_samples or the bandwidth "
                f"({option.bandwidth}), or raise max_grid_memory"
            )

    def samples(self, bandwidth: int) -> int:
        """Euler-angle samples per axis for ``bandwidth``; ``ValueError`` when too few."""
        samples = self.search_samples or 4 * bandwidth
        if samples < 2 * bandwidth - 1:
            raise ValueError(
                f"search_samples must be >= 2 * bandwidth - 1 = {2 * bandwidth - 1}, got "
                f"{samples}: raise it or lower the bandwidth"
            )
        return samples
