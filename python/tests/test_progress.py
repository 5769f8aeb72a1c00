"""Progress, cancellation (callback and Ctrl-C), the GIL, thread counts."""
import os
import signal
import threading
import time

import numpy as np
import pytest

import tessel
from conftest import fibonacci_sphere, sphere


def test_progress_reports_stages():
    seen = []
    mesh = tessel.reconstruct(fibonacci_sphere(5000), method="greedy",
                              progress=lambda stage, f: seen.append((stage, f)))
    assert len(mesh.faces) > 0
    assert seen and all(isinstance(s, str) and 0.0 <= f <= 1.0 for s, f in seen)
    assert "greedy" in {s for s, _ in seen}


def test_progress_returning_true_cancels():
    calls = []

    def stop(stage, f):
        calls.append(stage)
        return len(calls) >= 3

    with pytest.raises(tessel.CancelledError) as e:
        tessel.reconstruct(fibonacci_sphere(5000), method="greedy", progress=stop)
    assert e.value.status == tessel._lib.STATUS["TESSEL_ERR_CANCELLED"]
    assert len(calls) == 3  # not called again once cancelled


class Stop(Exception):
    pass


@pytest.mark.parametrize("method", ["greedy", "smooth"])
def test_progress_raising_cancels_and_propagates(method):
    def boom(stage, f):
        if f > 0.2:
            raise Stop(stage)

    with pytest.raises(Stop):
        tessel.reconstruct(sphere(5000, noise=0.01), method=method, progress=boom)


def test_progress_on_other_functions():
    pts = sphere(3000, noise=0.005)
    for fn in (lambda p: tessel.smooth(pts, progress=p),
               lambda p: tessel.simplify(pts, progress=p),
               lambda p: tessel.normals(pts, progress=p)):
        stages = []
        fn(lambda s, f: stages.append(s))
        assert stages
        with pytest.raises(tessel.CancelledError):
            fn(lambda s, f: True)


def test_keyboard_interrupt_in_the_callback():
    def ctrl_c(stage, f):
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        tessel.reconstruct(fibonacci_sphere(3000), method="greedy", progress=ctrl_c)


def test_sigint_cancels_cleanly():
    """A real SIGINT while the library runs (sent from the progress callback,
    so it lands mid-call): the call stops at the next progress report and
    raises KeyboardInterrupt; the handler is Python's again afterwards."""
    calls = []

    def send(stage, f):
        calls.append(stage)
        if len(calls) == 2:
            os.kill(os.getpid(), signal.SIGINT)

    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    with pytest.raises(KeyboardInterrupt):
        tessel.reconstruct(sphere(20000, noise=0.01), method="smooth", progress=send)
    assert len(calls) <= 4
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler
    # Nothing is left in a bad state: the next call works.
    assert tessel.check(tessel.reconstruct(fibonacci_sphere(2000)))["valid"]


def test_sigint_without_a_progress_callable():
    """Ctrl-C from another thread (as a terminal sends it) during a long
    call that has no Python progress callable: cancelled well before the
    end."""
    pts = sphere(150000, noise=0.01, seed=2)
    t0 = time.perf_counter()
    full = tessel.reconstruct(pts[:40000], method="smooth").summary["seconds"]
    expected = full * len(pts) / 40000
    killer = threading.Timer(0.3, os.kill, (os.getpid(), signal.SIGINT))
    t0 = time.perf_counter()
    killer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            tessel.reconstruct(pts, method="smooth")
    finally:
        killer.join()
    took = time.perf_counter() - t0
    assert took < 0.3 + 0.5 * expected, (took, expected)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_the_gil_is_released():
    """Another Python thread runs while the library works."""
    pts = sphere(60000, noise=0.01, seed=3)
    ticks = [0]
    done = threading.Event()

    def spin():
        while not done.is_set():
            ticks[0] += 1
            time.sleep(0.001)

    t = threading.Thread(target=spin)
    t.start()
    try:
        t0 = time.perf_counter()
        tessel.reconstruct(pts, method="smooth", threads=1)
        took = time.perf_counter() - t0
    finally:
        done.set()
        t.join()
    # About one tick per millisecond if the thread was free to run.
    assert ticks[0] > 0.3 * took * 1000, (ticks[0], took)


def test_calls_from_several_threads():
    pts = [fibonacci_sphere(3000 + 500 * i) for i in range(3)]
    out = [None] * 3

    def work(i):
        out[i] = tessel.reconstruct(pts[i], method="greedy", progress=lambda s, f: None)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for i in range(3):
        ref = tessel.reconstruct(pts[i], method="greedy")
        np.testing.assert_array_equal(out[i].faces, ref.faces)


def test_results_do_not_depend_on_threads():
    pts = sphere(8000, noise=0.01, seed=6)
    a = tessel.reconstruct(pts, method="smooth", threads=1)
    b = tessel.reconstruct(pts, method="smooth", threads=2)
    np.testing.assert_array_equal(a.faces, b.faces)
    assert a.xyz.tobytes() == b.xyz.tobytes()


def test_log_messages_go_to_logging(caplog):
    """The library's log messages reach the 'tessel' logger (here: why the
    grid mode refuses a cloud without a grid)."""
    import logging
    caplog.set_level(logging.DEBUG, logger="tessel")
    with pytest.raises(tessel.InvalidArgumentError):
        tessel.reconstruct(fibonacci_sphere(3000), method="grid")
    assert any(r.name == "tessel" and "organized" in r.getMessage() for r in caplog.records), \
        [r.getMessage() for r in caplog.records]
