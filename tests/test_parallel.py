"""Threads share out the global search's placements and climbs without changing a bit of
the result (o3d_spectral.common.parallel)."""

import numpy as np
import pytest

import o3d_spectral
from o3d_spectral.common.parallel import one_open3d_thread, resolved_workers, thread_map
from o3d_spectral.synthetic.scenes import make_instance
from o3d_spectral.synthetic.suite import instance_rng


def test_thread_map_keeps_the_items_order():
    items = list(range(50))
    assert thread_map(lambda x: x * x, items, 4) == [x * x for x in items]
    assert thread_map(lambda x: x, [], None) == []
    assert resolved_workers(None) >= 1 and resolved_workers(3) == 3


def test_workers_must_be_a_positive_count():
    with pytest.raises(ValueError, match="workers"):
        o3d_spectral.GlobalSearchOption(workers=0)


@pytest.mark.slow
@pytest.mark.parametrize("condition", ["cluttered", "partial"])
def test_the_result_is_the_same_to_the_bit_whatever_the_workers(condition):
    """A scene (focused searches, climbs on focused EGIs) and a view whose climbs run
    (no confirmation): one thread against four."""
    instance = make_instance(condition, "power_drill", rng=instance_rng(7, 3))
    results = [
        o3d_spectral.registration_spectral_global(
            instance.source, instance.target, 0.008,
            search=o3d_spectral.GlobalSearchOption(workers=workers, confirm=False))
        for workers in (1, 4)
    ]
    np.testing.assert_array_equal(results[0].transformation, results[1].transformation)
    assert [s for _, s in results[0].hypotheses] == [s for _, s in results[1].hypotheses]
    assert results[0].fitness == results[1].fitness


@pytest.mark.slow
def test_the_confirmation_is_the_same_whatever_the_workers():
    """A whole model against its view, confirmed early: on one thread the rivals are
    polished only where the best fits, on four all the candidates side by side."""
    instance = make_instance("full", "power_drill", rng=instance_rng(7, 3))
    results = [
        o3d_spectral.registration_spectral_global(
            instance.source, instance.target, 0.008,
            search=o3d_spectral.GlobalSearchOption(workers=workers))
        for workers in (1, 4)
    ]
    assert results[0].confirmed
    np.testing.assert_array_equal(results[0].transformation, results[1].transformation)
    assert (results[0].fit, results[0].rival_fit) == (results[1].fit, results[1].rival_fit)


def test_open3d_runs_on_one_thread_until_the_last_overlapping_block_closes():
    import open3d as o3d

    before = o3d.utility.get_max_threads()
    with one_open3d_thread():
        with one_open3d_thread():  # another thread's ICP, started meanwhile
            assert o3d.utility.get_max_threads() == 1
        assert o3d.utility.get_max_threads() == 1
    assert o3d.utility.get_max_threads() == before


def test_omp_num_threads_caps_the_default_workers(monkeypatch):
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert resolved_workers(None) == 1
    assert resolved_workers(3) == 3  # an explicit count is kept
    monkeypatch.setenv("OMP_NUM_THREADS", "")
    assert resolved_workers(None) >= 1


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="needs fork")
def test_a_process_forked_after_a_threaded_call_runs_its_own_threads():
    """The parent's pool has no threads in a forked child: the child must not wait on it."""
    import multiprocessing

    assert thread_map(lambda x: x + 1, range(8), 2) == list(range(1, 9))  # pool made here
    with multiprocessing.get_context("fork").Pool(1) as pool:
        result = pool.apply_async(thread_map, (abs, [-1, -2, -3], 2))
        assert result.get(timeout=30) == [1, 2, 3]


@pytest.mark.slow
def test_two_scans_are_registered_the_same_whatever_the_workers():
    """Dragon scans 96 degrees apart, without the confirmation: the sweep's batches, the
    climbs and the ascent's coarse starts on one thread against four."""
    from o3d_spectral.harness.real import load_cases

    case = load_cases(["dragon_96"])[0]
    results = [
        o3d_spectral.registration_spectral_global(
            case.source, case.target, 0.005,
            search=o3d_spectral.GlobalSearchOption(workers=workers, confirm=False))
        for workers in (1, 4)
    ]
    assert {"sweep", "ascent"} <= set(results[0].stage_times)
    np.testing.assert_array_equal(results[0].transformation, results[1].transformation)
    assert [s for _, s in results[0].hypotheses] == [s for _, s in results[1].hypotheses]
