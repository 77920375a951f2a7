"""The report's plots: the numbers they draw, and the files they write."""

import numpy as np
import pytest

pandas = pytest.importorskip("pandas", reason="the harness extra is not installed")
pytest.importorskip("matplotlib", reason="the harness extra is not installed")
from PIL import Image  # noqa: E402  (a dependency of matplotlib)

from o3d_spectral.harness._plotting import decade_label  # noqa: E402
from o3d_spectral.harness.convergence_plot import median_curves, padded_curves  # noqa: E402
from o3d_spectral.harness.figures import (  # noqa: E402
    ANGLE_BINS_DEG,
    plot_convergence,
    plot_cumulative_errors,
    plot_success_vs_angle,
    plot_times,
    success_by_angle,
)


def _frame(rng, methods=("spectral", "icp"), suites=("full", "partial"), n=30):
    """Rows as ``load_results`` gives them: curves for the spectral methods only."""
    rows = []
    for suite in suites:
        for index in range(n):
            for method in methods:
                error = float(rng.lognormal(0.0, 2.0))
                curve = list(90 * np.exp(-np.arange(rng.integers(3, 30)) / 5) + error)
                rows.append(
                    {
                        "suite": suite,
                        "index": index,
                        "method": method,
                        "condition": suite,
                        "init_angle_deg": float(rng.uniform(0, 180)),
                        "success": error < 5,
                        "error": None,
                        "time_s": float(rng.lognormal(-1, 1)),
                        "rotation_error_sym_deg": error,
                        "translation_error_sym_m": error / 1e3,
                        "curve_rotation_deg": curve if method.startswith("spectral") else None,
                        "curve_translation_m": curve if method.startswith("spectral") else None,
                    }
                )
    return pandas.DataFrame(rows)


def test_success_by_angle_is_pandas_cut_and_mean():
    rng = np.random.default_rng(0)
    angles = np.concatenate([rng.uniform(0, 180, 200), ANGLE_BINS_DEG, [-1.0, 181.0, np.nan]])
    success = rng.random(len(angles)) < 0.5
    runs = pandas.DataFrame({"init_angle_deg": angles, "success": success.astype(object)})
    runs.loc[3, "success"] = None  # unknown: left out of its bin
    bins = pandas.cut(runs["init_angle_deg"], ANGLE_BINS_DEG, include_lowest=True)
    expected = runs["success"].astype(float).groupby(bins, observed=False).mean()
    np.testing.assert_array_equal(success_by_angle(runs), expected.to_numpy())


def test_curves_are_padded_with_their_last_value():
    padded = padded_curves([[3.0, 2.0, 1.0], [5.0], [4.0, 0.5]])
    np.testing.assert_array_equal(padded, [[3, 2, 1], [5, 5, 5], [4, 0.5, 0.5]])


def test_the_successes_median_is_as_long_as_their_longest_curve():
    curves = [[8.0, 4.0, 2.0, 1.0], [6.0, 3.0], [2.0, 1.0, 0.5]]
    (everyone, _, _), (wins, colour, _) = median_curves(curves, np.array([False, True, True]), 10.0)
    np.testing.assert_allclose(everyone, [60, 30, 20, 10])
    np.testing.assert_allclose(wins, [40, 20, 17.5])
    assert colour == "darkgreen"
    assert len(median_curves(curves, np.zeros(3, dtype=bool), 1.0)) == 1  # no successes, no line


@pytest.mark.parametrize(
    ("value", "label"), [(1e-3, "10⁻³"), (1.0, "10⁰"), (1e4, "10⁴"), (2e-3, "0.002")]
)
def test_log_ticks_are_labelled_in_plain_text(value, label):
    assert decade_label(value) == label


@pytest.mark.slow
def test_every_figure_is_written_as_an_opaque_png(tmp_path):
    frame = _frame(np.random.default_rng(1))
    written = [
        plot_success_vs_angle(frame, tmp_path / "angle.png"),
        plot_cumulative_errors(frame, tmp_path / "cdf.png", thresholds=None),
        plot_times(frame, tmp_path / "time.png"),
    ]
    for path in written:
        with Image.open(path) as image:
            assert image.mode == "RGB" and image.size[0] > 500


def test_convergence_figures_of_methods_on_other_suites_have_their_own_rows(tmp_path):
    rng = np.random.default_rng(2)
    frame = pandas.concat(
        [_frame(rng, ("spectral",), ("full", "partial")), _frame(rng, ("spectral_b",), ("full",))]
    )
    paths = {m: tmp_path / f"convergence_{m}.png" for m in ("spectral", "spectral_b")}
    assert plot_convergence(frame, paths) == paths
    with Image.open(paths["spectral"]) as two, Image.open(paths["spectral_b"]) as one:
        assert two.size[0] == one.size[0] and two.size[1] > one.size[1]


def test_no_spectral_method_no_convergence_figure():
    frame = _frame(np.random.default_rng(3), methods=("icp",))
    assert (
        plot_convergence(frame.drop(columns=["curve_rotation_deg", "curve_translation_m"]), {})
        == {}
    )
