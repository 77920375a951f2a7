"""Fixed, seeded scene suites on disk: generation, loading and pictures.

A suite is a folder with one ``manifest.json`` and two binary PLY files per instance
(``NNNN_source.ply``, ``NNNN_target.ply``); the format is described in ``docs/suites.md``.
Instance ``i`` of a suite with seed ``s`` draws all its randomness from
``numpy.random.SeedSequence(s, spawn_key=(i,))``, so a suite is the same byte for byte
whatever the number of worker processes.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import open3d as o3d

from o3d_spectral.common import extras
from o3d_spectral.io.files import atomic_write_cloud, check_cloud_file, check_finite
from o3d_spectral.io.folder_lock import folder_lock, foreign_entries
from o3d_spectral.synthetic.constants import VERSION
from o3d_spectral.synthetic.instance import CONDITIONS, Instance, SceneOptions
from o3d_spectral.synthetic.manifest import atomic_write_text, instance_path, read_manifest
from o3d_spectral.synthetic.models import model_names
from o3d_spectral.synthetic.scenes import make_instance
from o3d_spectral.synthetic.sensor import CameraIntrinsics, DepthNoise

__all__ = [
    "MANIFEST",
    "Suite",
    "instance_rng",
    "load_suite",
    "make_suite",
    "save_instance_figure",
]

MANIFEST = "manifest.json"
#: The manifest's format (its version: :data:`o3d_spectral.synthetic.constants.VERSION`).
FORMAT = "o3d-spectral-suite"


def instance_rng(seed: int, index: int) -> np.random.Generator:
    """The random generator of instance ``index`` in a suite with ``seed``."""
    return np.random.default_rng(np.random.SeedSequence(seed, spawn_key=(index,)))


def _write_cloud(path: Path, points: np.ndarray, normals: np.ndarray, labels=None) -> None:
    """Binary little-endian PLY, float32 positions and normals, optional int32 object_id."""
    cloud = o3d.t.geometry.PointCloud()
    cloud.point.positions = o3d.core.Tensor(np.ascontiguousarray(points, dtype=np.float32))
    cloud.point.normals = o3d.core.Tensor(np.ascontiguousarray(normals, dtype=np.float32))
    if labels is not None:
        cloud.point.object_id = o3d.core.Tensor(
            np.ascontiguousarray(labels, dtype=np.int32).reshape(-1, 1)
        )
    atomic_write_cloud(path, len(points), lambda name: o3d.t.io.write_point_cloud(name, cloud))


def _build(task: tuple[str, str, int, int, SceneOptions, str]) -> dict:
    """Generate instance ``index`` and write its clouds; return its manifest entry."""
    condition, name, seed, index, options, out_dir = task
    instance = make_instance(condition, name, rng=instance_rng(seed, index), options=options)
    source_file, target_file = f"{index:04d}_source.ply", f"{index:04d}_target.ply"
    _write_cloud(
        Path(out_dir) / source_file,
        np.asarray(instance.source.points),
        np.asarray(instance.source.normals),
    )
    _write_cloud(
        Path(out_dir) / target_file,
        np.asarray(instance.target.points),
        np.asarray(instance.target.normals),
        instance.target_labels,
    )
    return {
        "index": index,
        "source": source_file,
        "target": target_file,
        "T_gt": instance.T_gt.tolist(),
        "source_from_model": instance.source_from_model.tolist(),
        **instance.metadata,
    }


def _options_json(options: SceneOptions) -> dict:
    return json.loads(json.dumps(dataclasses.asdict(options)))


def _options_from_json(data: dict) -> SceneOptions:
    fields = {k: tuple(v) if isinstance(v, list) else v for k, v in data.items()}
    fields["intrinsics"] = CameraIntrinsics(**data["intrinsics"])
    fields["noise"] = DepthNoise(**data["noise"])
    return SceneOptions(**fields)


def _check_suite_arguments(condition: str, n: int, seed: int, workers: int) -> None:
    if condition not in CONDITIONS:
        raise ValueError(f"condition must be one of {', '.join(CONDITIONS)}; got {condition!r}")
    if n < 1:
        raise ValueError(f"n must be >= 1, got {n}")
    if seed < 0:
        raise ValueError(f"seed must be >= 0, got {seed}")
    if workers < 1:
        raise ValueError(f"workers must be >= 1, got {workers}")


def _build_all(tasks: list[tuple], workers: int, *, desc: str, progress: bool) -> list[dict]:
    """Manifest entries of ``tasks`` (see :func:`_build`), in order, from ``workers``
    processes (this one when 1)."""
    tqdm = extras.require("tqdm", "suite generation (its progress bar)").tqdm
    bar = tqdm(total=len(tasks), desc=desc, unit="inst",
               disable=None if progress else True)  # None: on a terminal only
    if workers == 1:
        entries = []
        for task in tasks:
            entries.append(_build(task))
            bar.update()
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            entries = []
            for entry in pool.map(_build, tasks):
                entries.append(entry)
                bar.update()
    bar.close()
    return entries


def _check_empty(out: Path) -> None:
    """``ValueError`` naming ``out`` unless it is an empty folder (but for the claim of
    the run checking it: :mod:`~o3d_spectral.io.folder_lock`)."""
    if foreign_entries(out):
        raise ValueError(
            f"out_dir {str(out)!r} is not empty: write the suite to a new folder (or remove "
            "this one first)")


def make_suite(
    condition: str,
    n: int,
    seed: int,
    out_dir: str | Path,
    *,
    options: SceneOptions | None = None,
    workers: int = 1,
    progress: bool = True,
) -> Path:
    """Generate a suite of ``n`` instances and write it to ``out_dir``.

    Instance ``i`` uses model ``model_names()[i % 12]``, so 240 instances hold 20 per object.

    Parameters
    ----------
    condition : {"full", "partial", "occluded", "cluttered"}
        See :mod:`o3d_spectral.synthetic.scenes`.
    n : int
        Number of instances (>= 1).
    seed : int
        Suite seed (>= 0); the same seed gives byte-identical files.
    out_dir : str or Path
        Folder to create, or an empty one (instance files and ``manifest.json``): a suite
        written over another would leave the other's files, and a run resumed on it would
        keep rows of the other's instances.
    options : SceneOptions, optional
        Generator settings, stored in the manifest.
    workers : int, optional
        Worker processes; the output does not depend on it.
    progress : bool, optional
        Show a tqdm progress bar, when stderr is a terminal (its frames would fill a log
        or a pipe).

    Returns
    -------
    Path
        Path of the written manifest.
    """
    _check_suite_arguments(condition, n, seed, workers)
    options = SceneOptions() if options is None else options
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise ValueError(f"out_dir {str(out)!r} is a file, not a folder: choose a folder")
    names = model_names()
    tasks = [(condition, names[i % len(names)], seed, i, options, str(out)) for i in range(n)]
    with folder_lock(out, "o3d-spectral make-suite"):  # one suite at a time into a folder
        _check_empty(out)
        entries = _build_all(tasks, workers, desc=f"{condition} suite", progress=progress)
    manifest = {
        "format": FORMAT,
        "version": VERSION,
        "condition": condition,
        "n": n,
        "seed": seed,
        "options": _options_json(options),
        "instances": entries,
    }
    path = out / MANIFEST
    atomic_write_text(path, json.dumps(manifest, indent=1) + "\n")
    return path


class Suite(Sequence[Instance]):
    """A suite on disk; instances are read lazily by index.

    Attributes
    ----------
    root : Path
        The suite folder.
    manifest : dict
        The parsed ``manifest.json``.
    options : SceneOptions
        The generator settings the suite was made with.
    """

    def __init__(self, root: str | Path) -> None:
        self.root = Path(root)
        path = self.root / MANIFEST
        if not path.is_file():
            raise FileNotFoundError(f"no {MANIFEST} in {self.root}; make one with make-suite")
        self.manifest = read_manifest(path)
        if self.manifest["format"] != FORMAT or self.manifest["version"] != VERSION:
            raise ValueError(
                f"{path} is not an {FORMAT} version {VERSION} manifest "
                f"(format={self.manifest['format']!r}, version={self.manifest['version']!r})"
            )
        try:
            self.options = _options_from_json(self.manifest["options"])
        except (TypeError, ValueError, KeyError, AttributeError) as error:
            raise ValueError(f"{path}: bad options ({type(error).__name__}: {error})") from None

    def __repr__(self) -> str:
        return (
            f"Suite(root={str(self.root)!r}, condition={self.condition!r}, n={len(self)}, "
            f"seed={self.manifest['seed']})"
        )

    @property
    def condition(self) -> str:
        """The suite's condition."""
        return self.manifest["condition"]

    def __len__(self) -> int:
        return len(self.manifest["instances"])

    def __getitem__(self, index: int) -> Instance:  # type: ignore[override]
        """Instance ``index``, read from its files; ``FileNotFoundError`` or ``ValueError``
        naming the file when one is missing, truncated or corrupt."""
        entry = self.manifest["instances"][index]
        source = _read_instance_cloud(self.root, entry["source"])
        target = _read_instance_cloud(self.root, entry["target"])
        if "object_id" not in target.point:
            raise ValueError(f"{self.root / entry['target']}: no object_id per point; "
                             "make the suite again")
        labels = target.point.object_id.numpy().ravel().astype(np.int64)
        if len(labels) != len(target.point.positions):
            raise ValueError(f"{self.root / entry['target']}: object_id does not match points")
        skip = {"index", "source", "target", "T_gt", "source_from_model"}
        return Instance(
            source=source.to_legacy(),
            target=target.to_legacy(),
            T_gt=np.array(entry["T_gt"]),
            target_labels=labels,
            source_from_model=np.array(entry["source_from_model"]),
            metadata={k: v for k, v in entry.items() if k not in skip},
        )

    def __iter__(self) -> Iterator[Instance]:
        for index in range(len(self)):
            yield self[index]


def _read_instance_cloud(root: Path, name: str) -> o3d.t.geometry.PointCloud:
    """One instance file, checked: inside ``root``, complete, with finite points and
    normals (``FileNotFoundError`` or ``ValueError`` naming it otherwise)."""
    path = check_cloud_file(instance_path(root, name))
    cloud = o3d.t.io.read_point_cloud(str(path))
    if "positions" not in cloud.point or len(cloud.point.positions) == 0:
        raise ValueError(f"{path}: Open3D read no points from it; make the suite again")
    if "normals" not in cloud.point:
        raise ValueError(f"{path}: no normals; make the suite again")
    arrays = np.hstack([cloud.point.positions.numpy(), cloud.point.normals.numpy()])
    check_finite(arrays, path, what="points (with their normals)")
    return cloud


def load_suite(directory: str | Path) -> Suite:
    """Open the suite in ``directory`` (see :class:`Suite`); instances load on access."""
    return Suite(directory)


def _draw_panel(ax, label: str, layers: list[tuple], view: Callable) -> None:
    """Scatter ``layers`` (points, size, colour, alpha), each passed through ``view``, on
    the 3-D axes ``ax``: camera frame (x right, y down, z forward) drawn as (x, depth, up)."""
    shown = []
    for points, size, colour, alpha in layers:
        points = view(points)
        if len(points):
            xyz = points[:, 0], points[:, 2], -points[:, 1]
            ax.scatter(*xyz, s=size, c=colour, alpha=alpha, depthshade=False)
            shown.append(points)
    shown = np.concatenate(shown)
    ax.set_box_aspect(np.ptp(shown[:, [0, 2, 1]], axis=0) + 1e-3)
    ax.view_init(elev=20, azim=-75)
    ax.set_title(label, fontsize=10)
    ax.set_xlabel("x (m)", fontsize=8)
    ax.set_ylabel("z (m)", fontsize=8)
    ax.set_zlabel("-y (m)", fontsize=8)
    ax.tick_params(labelsize=6)


def save_instance_figure(
    instance: Instance, path: str | Path, *, max_points: int = 6000, title: str | None = None
) -> Path:
    """Save a PNG of an instance: the input pair, and the source moved by ``T_gt``.

    Source points are blue, the target's object points orange, other objects dark grey and
    table or occluder points light grey. Points are drawn in the target's frame, seen from
    behind the camera for scans; the second panel is cropped to 5 cm around the target
    object. At most ``max_points`` per cloud are drawn (a fixed subsample).
    """
    from o3d_spectral.plots import pyplot

    plt = pyplot()

    rng = np.random.default_rng(0)

    def subsample(points: np.ndarray, k: int) -> np.ndarray:
        return points if len(points) <= k else points[rng.choice(len(points), k, replace=False)]

    source = np.asarray(instance.source.points)
    moved = source @ instance.T_gt[:3, :3].T + instance.T_gt[:3, 3]
    target = np.asarray(instance.target.points)
    labels = instance.target_labels
    target_obj = subsample(target[labels == 0], max_points)
    others = subsample(target[labels > 0], max_points)
    table = subsample(target[labels < 0], 2 * max_points)
    lo, hi = target_obj.min(axis=0) - 0.05, target_obj.max(axis=0) + 0.05

    def crop(points: np.ndarray) -> np.ndarray:
        return points[np.all((points >= lo) & (points <= hi), axis=1)]

    fig = plt.figure(figsize=(10, 4.6), dpi=90)
    panels = [
        ("input: source and target", source, lambda p: p),
        ("ground truth: T_gt @ source (close-up)", moved, crop),
    ]
    for k, (label, src, view) in enumerate(panels):
        layers = [(table, 0.3, "0.8", 1.0), (others, 0.3, "0.45", 1.0)]
        layers += [
            (target_obj, 0.6, "tab:orange", 0.35),
            (subsample(src, max_points), 0.4, "tab:blue", 1.0),
        ]
        _draw_panel(fig.add_subplot(1, 2, k + 1, projection="3d"), label, layers, view)
    meta = instance.metadata
    fig.suptitle(
        title
        or (
            f"{meta['condition']}: {meta['object']}, initial angle "
            f"{meta['init_angle_deg']:.0f} deg, visible {meta['visible_fraction']:.0%}, "
            f"occlusion {meta['occlusion']:.0%}  (blue: source, orange: target object)"
        ),
        fontsize=10,
    )
    fig.tight_layout()
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path
