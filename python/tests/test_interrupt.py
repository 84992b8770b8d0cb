"""Ctrl-C stops a render; the GIL is released while rendering."""

import os
import signal
import threading
import time

import pytest

import photonlab

# About a minute of path tracing on two cores: far longer than the test waits.
LONG = dict(builtin="cornell", integrator="path", spp=20000, resolution=(96, 96))


def test_ctrl_c_interrupts_a_render():
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        photonlab.render(**LONG)
    assert time.monotonic() - t0 < 5.0
    timer.join()
    # The cancel flag is cleared: the next render runs to the end.
    img = photonlab.render(spp=1, resolution=(8, 8))
    assert img.mean() > 0


def test_ctrl_c_interrupts_a_progressive_render():
    timer = threading.Timer(0.5, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        photonlab.render(integrator="sppm", passes=100000, resolution=(64, 64))
    assert time.monotonic() - t0 < 5.0
    timer.join()


def test_gil_is_released_while_rendering():
    ticks = []
    stop = threading.Event()

    def tick():
        while not stop.is_set():
            ticks.append(time.monotonic())
            time.sleep(0.01)

    t = threading.Thread(target=tick)
    t.start()
    t0 = time.monotonic()
    photonlab.render(integrator="path", spp=64, resolution=(64, 64))
    elapsed = time.monotonic() - t0
    stop.set()
    t.join()
    during = [x for x in ticks if t0 < x < t0 + elapsed]
    # A thread blocked on the GIL would not tick at all during the render.
    assert elapsed < 0.2 or len(during) >= 0.3 * elapsed / 0.01, (elapsed, len(during))
