"""Recall of the global search's rotation candidates, per angle and per generator, and the
stage of the search that loses the truth.

Pairs: the turntable pairs of the 12 bundled models (two depth views, the turntable turned
30-135 degrees between them, at each of the two elevations, each view in its own camera
frame; seed 200 + the pair's index within its angle, as ``eval/bench_speed.py`` draws its
turntable groups), 8 mm; and the bundled dragon scan pairs 24-120 degrees apart, the
source turned by ``--rotations`` seeded random rotations (``real.rotated_cases``), 5 mm.
A rotation is *right* when its symmetry-aware rotation error (the smallest over the
model's symmetries, ``harness.errors.symmetric_rotation_error``) is under
:data:`RIGHT_DEG`.

For each pair the search runs stage by stage as ``registration_spectral_global`` runs it
(``GlobalSearch``: rank, confirm, sweep, rank and confirm again, climbs, ascent, the
polish and the closer placed pose), with its defaults on one thread, and the script
records:

* per generator (``egi``: the EGI correlation's peaks; ``shell``: the shells' peaks;
  ``sweep``: the 16 best of the sweep of SO(3)), in the generator's own order (its score):
  the index of the first right candidate, hence recall@k for k = 1, 4, 16 and all, and
  the error of its nearest candidate;
* after the placement ranking (by the placed peak height; the sweep's candidates ranked
  with the others, as the search ranks them after a sweep; between two scans only the
  best on a coarse grid are placed): the rank of the generator's first right candidate;
* whether the confirmation's pose is right and whether it stopped the search, whether a
  climbed start, the climbs' best, the ascent and the final result (after the turns of a
  doubtful pose, ``o3d_spectral.opinions.turn_opinion``) are right; the stage
  that loses the truth is the first of those after which no right pose is left, on pairs
  whose final pose is wrong.

Writes ``pairs.csv`` (one row per pair), ``generators.csv`` and ``stages.csv`` (per
dataset and angle), and ``summary.md`` (both tables) to ``--out``.

Usage: python eval/recall_generators.py --out out/recall_generators
       [--angles 90 135] [--limit 3] [--rotations 1] [--workers 2]
"""

from __future__ import annotations

import os

for _var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS",
             "NUMEXPR_NUM_THREADS", "NUMBA_NUM_THREADS"):
    os.environ.setdefault(_var, "1")  # one thread per pair

import argparse  # noqa: E402
import sys  # noqa: E402
from concurrent.futures import ProcessPoolExecutor  # noqa: E402
from dataclasses import dataclass  # noqa: E402
from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import open3d as o3d  # noqa: E402
from tqdm import tqdm  # noqa: E402

from o3d_spectral import GlobalSearchOption  # noqa: E402
from o3d_spectral.common.stages import StageClock  # noqa: E402
from o3d_spectral.evidence.diagnostics import may_be_wrong  # noqa: E402
from o3d_spectral.harness import real  # noqa: E402
from o3d_spectral.harness.errors import symmetric_rotation_error  # noqa: E402
from o3d_spectral.harness.metrics import instance_score  # noqa: E402
from o3d_spectral.harness.writers import write_rows  # noqa: E402
from o3d_spectral.opinions import turn_opinion  # noqa: E402
from o3d_spectral.registration import placed_result, searched  # noqa: E402
from o3d_spectral.run import DEFAULT_REFINEMENT, Run, finish, start  # noqa: E402
from o3d_spectral.search import GlobalSearch  # noqa: E402
from o3d_spectral.search.candidates import swept_candidates  # noqa: E402
from o3d_spectral.synthetic.models import model_names  # noqa: E402
from o3d_spectral.synthetic.turntable import (  # noqa: E402
    TURNTABLE_ANGLES,
    TURNTABLE_ELEVATIONS,
    turntable_pair,
)

o3d.utility.set_max_threads(1)
o3d.utility.set_verbosity_level(o3d.utility.VerbosityLevel.Error)

#: A candidate or pose within this many degrees of the truth (symmetry-aware) is right.
RIGHT_DEG = 10.0
#: The generators, as their candidates' keys name them.
GENERATORS = ("egi", "shell", "sweep")
#: Recall is reported among each generator's first k candidates (None: all of them).
KS = (1, 4, 16, None)
#: The dragon pairs' angles (degrees).
DRAGON_ANGLES = (24, 48, 72, 96, 120)
#: Where the truth can be lost, in the search's order; ``kept``: the final pose is right.
STAGES = ("candidates", "coarse", "confirmation", "ranking", "climbs", "ascent", "polish",
          "kept")
TURNTABLE_VOXEL = 0.008


@dataclass(frozen=True)
class Spec:
    """One pair, named well enough to be built again in a worker process."""

    dataset: str  # "turntable" or "dragon"
    angle: int
    index: int  # the pair's index within its angle (turntable) or the rotation (dragon)
    name: str


@dataclass
class Pair:
    """A pair's clouds, voxel and how to judge a rotation and a final pose."""

    spec: Spec
    source: o3d.geometry.PointCloud
    target: o3d.geometry.PointCloud
    voxel: float
    rotation_error: object  # (T 4x4) -> degrees, symmetry-aware
    score: object  # (T 4x4) -> (rotation deg, translation m, success)


def specs(angles: list[int], rotations: int, limit: int) -> list[Spec]:
    """The pairs of ``angles`` (turntable and dragon angles alike), at most ``limit`` of
    each dataset and angle."""
    out: list[Spec] = []
    turntable = [(n, e) for e in TURNTABLE_ELEVATIONS for n in model_names()]
    for angle in (a for a in TURNTABLE_ANGLES if a in angles):
        out += [Spec("turntable", angle, i, f"{n}_{e}")
                for i, (n, e) in enumerate(turntable[:limit])]
    for angle in (a for a in DRAGON_ANGLES if a in angles):
        cases = [(c.name, r) for c in real.load_cases([f"dragon_{angle}"])
                 for r in range(rotations)]
        out += [Spec("dragon", angle, r, f"{name}_r{r}") for name, r in cases[:limit]]
    return out


def build(spec: Spec) -> Pair:
    """The clouds and the judges of ``spec``."""
    if spec.dataset == "turntable":
        name, elevation = spec.name.rsplit("_", 1)
        pair = turntable_pair(name, spec.angle, int(elevation),
                              np.random.default_rng(200 + spec.index))
        return Pair(spec, pair.source, pair.target, TURNTABLE_VOXEL,
                    lambda T: symmetric_rotation_error(T, pair.T_gt, pair.symmetry),
                    instance_score(pair))
    case_name = spec.name.rsplit("_r", 1)[0]
    for turned, _, _, r in real.rotated_cases([f"dragon_{spec.angle}"], spec.index + 1):
        if turned.name == case_name and r == spec.index:
            return Pair(spec, turned.source, turned.target, real.VOXEL_SIZES["dragon_24"],
                        lambda T, case=turned: symmetric_rotation_error(T, case.T_gt,
                                                                        case.symmetry),
                        real.case_score(turned))
    raise ValueError(f"no dragon pair {spec.name}")


def rotation4(rotation: np.ndarray) -> np.ndarray:
    """A rotation (3, 3) as a 4x4 transform (the errors read its rotation only)."""
    T = np.eye(4)
    T[:3, :3] = rotation
    return T


def first_right(errors: list[float]) -> int | None:
    """The 0-based index of the first error under :data:`RIGHT_DEG`, or None."""
    return next((i for i, e in enumerate(errors) if e < RIGHT_DEG), None)


def generator_rows(pair: Pair, finder: GlobalSearch) -> dict[str, list[float]]:
    """Each generator's candidates' errors (degrees), in its own order; an empty list for
    a generator that does not apply to the pair."""
    candidates = finder.state.candidates or []
    if finder.sweeps:
        candidates = candidates + swept_candidates(finder.stepper, finder.moving,
                                                   finder.option.sweep_rotations,
                                                   finder.option.workers)
    return {g: [pair.rotation_error(rotation4(c.rotation)) for c in candidates
                if c.key[0] == g] for g in GENERATORS}


def placed_ranks(pair: Pair, hypotheses: list) -> dict[str, int | None]:
    """Per generator, the 1-based rank in ``hypotheses`` (best placed first) of its first
    right hypothesis, or None."""
    ranks: dict[str, int | None] = dict.fromkeys(GENERATORS)
    for rank, h in enumerate(hypotheses, start=1):
        generator = h.key[0][0] if h.key else ""
        if generator in ranks and ranks[generator] is None and \
                pair.rotation_error(rotation4(h.rotation)) < RIGHT_DEG:
            ranks[generator] = rank
    return ranks


def right(pair: Pair, pose: np.ndarray) -> bool:
    return bool(pair.rotation_error(pose) < RIGHT_DEG)


def confirmed_of(finder: GlobalSearch, ranking) -> tuple[object, object]:
    """The confirmation of ``ranking``'s best (None where it does not apply) and itself
    again where it confirmed (else None)."""
    if not finder.confirms:
        return None, None
    confirmation = finder.confirm(ranking)
    return confirmation, confirmation if confirmation.confirmed else None


def pipeline(pair: Pair, run: Run, finder: GlobalSearch) -> dict:
    """The search and polish of ``registration_spectral_global``, stage by stage; what
    each stage left, judged against the truth."""
    out: dict = {"swept": False}
    out["ranking_first"] = ranking = finder.rank()
    confirmation, confirmed = confirmed_of(finder, ranking)
    if confirmed is None and finder.sweeps:
        out["swept"] = True
        ranking = finder.rank(sweep=True)
        confirmation, confirmed = confirmed_of(finder, ranking)
    out["ranking"], out["confirmed"] = ranking, confirmed is not None
    out["confirmation_right"] = (None if confirmation is None
                                 else right(pair, confirmation.transformation))
    out["climbs_right"] = out["ascent_right"] = out["starts_right"] = None
    if confirmed is not None:
        best, pose, result = placed_result(run, confirmed)
    else:
        starts = ranking.hypotheses[: finder.option.climbs]
        out["starts_right"] = any(right(pair, rotation4(h.rotation)) for h in starts)
        best, pose, result, climbed = searched(run, finder, ranking, StageClock())
        out["climbs_right"] = right(pair, climbed)
        if finder.ascends:
            out["ascent_right"] = right(pair, pose)
    out["before_polish_right"] = right(pair, pose)
    climbed = list(result.hypotheses)
    result = finish(run, result, best, pose @ run.init, DEFAULT_REFINEMENT, None)
    if confirmed is None:
        placed = finder.closer_placed(ranking, run.moving_pose(result.transformation))
        if placed is not None:
            best, pose, result = placed_result(run, placed)
            result = finish(run, result, best, pose @ run.init, DEFAULT_REFINEMENT, None)
    if finder.option.turns and not run.situation.scene and may_be_wrong(result.confidence):
        result = turn_opinion(run, finder, result, climbed, finder.option.turns,
                              DEFAULT_REFINEMENT, None)
    out["transformation"] = np.asarray(result.transformation)
    return out


def lost_at(row: dict) -> str:
    """The first stage (:data:`STAGES`) after which no right pose was left, for a wrong
    final pose; ``kept`` for a right one."""
    if row["final_right"]:
        return "kept"
    checks = [("candidates", row["candidates_right"]), ("coarse", row["placed_right"]),
              ("confirmation", not row["confirmed"] or row["confirmation_right"]),
              ("ranking", row["starts_right"]), ("climbs", row["climbs_right"]),
              ("ascent", row["ascent_right"])]
    for stage, kept in checks:
        if kept is False:
            return stage
    return "polish"


def analyse(spec: Spec) -> dict:
    """One pair's row: per generator the first right candidate in its own order and after
    the placement ranking, and what each stage of the search left."""
    pair = build(spec)
    run = start(pair.source, pair.target, pair.voxel, np.eye(4), None, None, None)
    finder = GlobalSearch(run.stepper, run.moving, run.target, GlobalSearchOption(workers=1),
                          run.situation)
    stages = pipeline(pair, run, finder)
    errors = generator_rows(pair, finder)
    full = stages["ranking"] if stages["swept"] or not finder.sweeps else finder.rank(sweep=True)
    ranks = placed_ranks(pair, full.hypotheses)
    used = [g for g in GENERATORS if g != "sweep" or stages["swept"]]
    rotation_deg, translation_m, success = pair.score(stages["transformation"])
    row = {"dataset": spec.dataset, "angle": spec.angle, "pair": spec.name,
           "two_scans": finder.situation.two_scans, "swept": stages["swept"]}
    for g in GENERATORS:
        row[f"{g}_count"] = len(errors[g])
        row[f"{g}_first_right"] = first_right(errors[g])
        row[f"{g}_nearest_deg"] = min(errors[g], default=float("nan"))
        row[f"{g}_placed_rank"] = ranks[g]
    row["candidates_right"] = any(first_right(errors[g]) is not None for g in used)
    row["placed_right"] = any(right(pair, rotation4(h.rotation))
                              for h in stages["ranking"].hypotheses)
    first = placed_ranks(pair, stages["ranking_first"].hypotheses)
    row["first_ranking_rank"] = min((r for r in first.values() if r), default=None)
    for key in ("confirmed", "confirmation_right", "starts_right", "climbs_right",
                "ascent_right", "before_polish_right"):
        row[key] = stages[key]
    row["final_rotation_deg"], row["final_translation_m"] = rotation_deg, translation_m
    row["final_right"], row["success"] = bool(rotation_deg < RIGHT_DEG), bool(success)
    row["lost_at"] = lost_at(row)
    return row


def groups(rows: list[dict]) -> list[tuple[str, int, list[dict]]]:
    """The rows by (dataset, angle), turntable first, angles ascending."""
    keys = sorted({(r["dataset"], r["angle"]) for r in rows},
                  key=lambda k: (k[0] != "turntable", k[1]))
    return [(d, a, [r for r in rows if (r["dataset"], r["angle"]) == (d, a)]) for d, a in keys]


def share(flags: list[bool]) -> float:
    return float(np.mean(flags)) if flags else float("nan")


def generator_summary(rows: list[dict]) -> list[dict]:
    """Per dataset, angle and generator: recall@k in its own order, the share of pairs
    with a right candidate placed and the median placed rank of the first right one."""
    out = []
    for dataset, angle, picked in groups(rows):
        for g in GENERATORS:
            applied = [r for r in picked if int(r[f"{g}_count"]) > 0]
            line = {"dataset": dataset, "angle": angle, "generator": g, "n": len(applied)}
            for k in KS:
                line[f"recall_at_{k or 'all'}"] = share([
                    r[f"{g}_first_right"] is not None
                    and (k is None or r[f"{g}_first_right"] < k) for r in applied])
            placed = [r[f"{g}_placed_rank"] for r in applied if r[f"{g}_placed_rank"]]
            line["placed"] = share([r[f"{g}_placed_rank"] is not None for r in applied])
            line["median_placed_rank"] = float(np.median(placed)) if placed else float("nan")
            nearest = [float(r[f"{g}_nearest_deg"]) for r in applied]
            line["median_nearest_deg"] = float(np.median(nearest)) if nearest else float("nan")
            out.append(line)
    return out


def stage_summary(rows: list[dict]) -> list[dict]:
    """Per dataset and angle: success, the right share after each stage, and the count
    of wrong final poses by the stage that lost the truth."""
    out = []
    for dataset, angle, picked in groups(rows):
        line = {"dataset": dataset, "angle": angle, "n": len(picked),
                "success": share([r["success"] for r in picked]),
                "final_right": share([r["final_right"] for r in picked]),
                "candidates_right": share([r["candidates_right"] for r in picked]),
                "placed_right": share([r["placed_right"] for r in picked]),
                "confirmed": sum(bool(r["confirmed"]) for r in picked),
                "confirmed_wrong": sum(bool(r["confirmed"]) and not r["confirmation_right"]
                                       for r in picked),
                "confirmation_right": share([r["confirmation_right"] for r in picked
                                             if r["confirmation_right"] is not None]),
                "climbs_right": share([r["climbs_right"] for r in picked
                                       if r["climbs_right"] is not None])}
        for stage in STAGES:
            line[f"lost_{stage}"] = sum(r["lost_at"] == stage for r in picked)
        out.append(line)
    return out


def percent(value: float) -> str:
    return "-" if np.isnan(value) else f"{100 * value:.0f}%"


def number(value: float, digits: int) -> str:
    return "-" if np.isnan(value) else f"{value:.{digits}f}"


def generator_table(summary: list[dict]) -> str:
    head = ["dataset", "angle", "generator", "n", "recall@1", "recall@4", "recall@16",
            "recall@all", "a right one placed", "median placed rank", "median nearest (deg)"]
    lines = [[s["dataset"], str(s["angle"]), s["generator"], str(s["n"]),
              *(percent(float(s[f"recall_at_{k or 'all'}"])) for k in KS),
              percent(float(s["placed"])),
              *(number(float(s[k]), digits) for k, digits in (("median_placed_rank", 0),
                                                               ("median_nearest_deg", 1)))]
             for s in summary]
    return markdown(head, lines)


def stage_table(summary: list[dict]) -> str:
    head = ["dataset", "angle", "n", "success", "right at the end", "a right candidate",
            "a right one placed", "confirmed (wrong)", "confirmation's pose right",
            "climbs' best right", *(f"lost: {s}" for s in STAGES[:-1])]
    lines = [[s["dataset"], str(s["angle"]), str(s["n"]),
              *(percent(float(s[k])) for k in ("success", "final_right", "candidates_right",
                                               "placed_right")),
              f"{s['confirmed']} ({s['confirmed_wrong']})",
              percent(float(s["confirmation_right"])), percent(float(s["climbs_right"])),
              *(str(s[f"lost_{stage}"]) for stage in STAGES[:-1])] for s in summary]
    return markdown(head, lines)


def markdown(head: list[str], lines: list[list[str]]) -> str:
    rows = ["| " + " | ".join(head) + " |", "|" + " --- |" * len(head)]
    return "\n".join(rows + ["| " + " | ".join(line) + " |" for line in lines])


def analysed(todo: list[Spec], workers: int) -> list[dict]:
    """The rows of ``todo``, in its order, on ``workers`` processes (progress on stderr)."""
    bar = tqdm(total=len(todo), desc="recall_generators", unit="pair", file=sys.stderr)
    if workers <= 1:
        rows = []
        for spec in todo:
            rows.append(analyse(spec))
            bar.update()
        bar.close()
        return rows
    with ProcessPoolExecutor(max_workers=workers) as pool:
        futures = [pool.submit(analyse, spec) for spec in todo]
        rows = []
        for future in futures:
            rows.append(future.result())
            bar.update()
    bar.close()
    return rows


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("out/recall_generators"))
    parser.add_argument("--angles", type=int, nargs="+",
                        default=sorted({*TURNTABLE_ANGLES, *DRAGON_ANGLES}),
                        help="turntable angles (30 45 60 90 120 135) and dragon angles "
                             "(24 48 72 96 120)")
    parser.add_argument("--limit", type=int, default=10**9,
                        help="at most this many pairs per dataset and angle")
    parser.add_argument("--rotations", type=int, default=2,
                        help="seeded random rotations of each dragon pair's source")
    parser.add_argument("--workers", type=int, default=1, help="processes, one pair each")
    args = parser.parse_args(argv)
    known = {*TURNTABLE_ANGLES, *DRAGON_ANGLES}
    if unknown := sorted(set(args.angles) - known):
        parser.error(f"--angles: no pairs at {unknown}; known: {sorted(known)}")
    rows = analysed(specs(args.angles, args.rotations, args.limit), args.workers)
    generators, stages = generator_summary(rows), stage_summary(rows)
    args.out.mkdir(parents=True, exist_ok=True)
    write_rows(args.out / "pairs.csv", rows)
    write_rows(args.out / "generators.csv", generators)
    write_rows(args.out / "stages.csv", stages)
    text = generator_table(generators) + "\n\n" + stage_table(stages)
    (args.out / "summary.md").write_text(text + "\n")
    print(text)
    print(f"wrote {args.out / 'pairs.csv'}, generators.csv, stages.csv, summary.md")


if __name__ == "__main__":
    main()
