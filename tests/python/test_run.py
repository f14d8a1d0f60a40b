"""Runs from Python: the engine's SequenceRunner, progress callbacks, outputs as arrays that
outlive the run, per-pass times, failures as exceptions, and the same frames as `kestrel run`."""
import gc
import threading
import time

import numpy as np
import pytest

import kestrel
from conftest import SVGF, cli, in_memory


def compiled_svgf(scene, *sets):
    g = kestrel.load_graph(SVGF, set=["input.path=" + scene["noisy"], *sets])
    port = in_memory(g)
    return g.compile(first_frame=1), port


def test_run_reads_the_last_frame_as_an_array(scene):
    c, port = compiled_svgf(scene)
    run = kestrel.run(c, frames="1-4")
    assert [f["frame"] for f in run.frames] == [1, 2, 3, 4]
    assert all(f["written"] and f["ms"] > 0 for f in run.frames)
    img = run.output(port)
    assert img.shape == (27, 48, 3) and img.dtype == np.float32
    assert np.isfinite(img).all() and img.mean() > 0
    with pytest.raises(kestrel.Error, match="not marked|marked"):
        run.output("diffuse.atrous0.color")


def test_array_outlives_graph_and_run(scene):
    c, port = compiled_svgf(scene)
    run = kestrel.run(c, frames=[1, 2])
    img = run.output(port)
    kept = img.copy()
    del run, c
    gc.collect()
    # The engine's memory is gone; the array owns its copy.
    churn = kestrel.run(compiled_svgf(scene, "*.sigmaL=1")[0], frames=[1, 2])
    del churn
    gc.collect()
    assert img.flags.owndata or img.base is not None
    np.testing.assert_array_equal(img, kept)


def test_progress_callback_sees_each_frame_and_its_outputs(scene):
    c, port = compiled_svgf(scene)
    seen, frames = [], []

    def progress(frame):
        seen.append((frame.frame, frame.index, frame.written, sorted(frame.pass_ms)))
        frames.append((frame, frame.output(port)))

    run = kestrel.run(c, frames="1-3", progress=progress)
    assert [s[0] for s in seen] == [1, 2, 3] and [s[1] for s in seen] == [0, 1, 2]
    assert seen[0][3] == sorted(c.execution_order)
    # Each callback's copy is that frame's: the last equals the run's last frame.
    np.testing.assert_array_equal(frames[-1][1], run.output(port))
    assert not np.array_equal(frames[0][1], frames[-1][1])
    # Outside its callback a frame's outputs are gone: an error, never a dangling view.
    with pytest.raises(kestrel.Error, match="only inside the progress callback"):
        frames[0][0].output(port)


def test_callback_false_stops_and_exceptions_propagate(scene):
    c, _ = compiled_svgf(scene)
    run = kestrel.run(c, frames="1-4", progress=lambda f: False)
    assert run.stopped and len(run.frames) == 1
    # Only False stops: a callback returning what it computed (an array, 0) runs on.
    for value in (0, None, np.zeros((2, 2)), ""):
        run = kestrel.run(c, frames="1-4", progress=lambda f, v=value: v)
        assert not run.stopped and len(run.frames) == 4

    def boom(frame):
        raise ValueError(f"boom at {frame.frame}")

    with pytest.raises(ValueError, match="boom at 1"):
        kestrel.run(c, frames="1-4", progress=boom)
    # The graph is still usable after a failed run.
    assert len(kestrel.run(c, frames="1-2").frames) == 2


def test_warmup_and_per_pass_times(scene):
    c, _ = compiled_svgf(scene)
    run = kestrel.run(c, frames="3-4", warmup=2)
    assert [(f["frame"], f["written"]) for f in run.frames] == \
        [(1, False), (2, False), (3, True), (4, True)]
    times = run.pass_times
    assert {t["frame"] for t in times} == {1, 2, 3, 4}
    assert {t["pass"] for t in times} == set(c.execution_order)
    assert all(t["ms"] >= 0 for t in times)


def test_missing_frame_raises_frame_error_or_is_skipped(scene):
    c, _ = compiled_svgf(scene)
    with pytest.raises(kestrel.FrameError, match="frame_0009.exr"):
        kestrel.run(c, frames=[1, 9])
    run = kestrel.run(c, frames=[1, 9, 2], skip_bad_frames=True)
    assert [f["frame"] for f in run.frames] == [1, 2]
    assert run.skipped[0]["frame"] == 9 and "frame_0009.exr" in run.skipped[0]["error"]


def test_same_frames_as_kestrel_run(scene, tmp_path):
    out_py = str(tmp_path / "py" / "frame_####.exr")
    out_cli = str(tmp_path / "cli" / "frame_####.exr")
    g = kestrel.load_graph(SVGF, set=["input.path=" + scene["noisy"], "output.path=" + out_py])
    kestrel.run(g.compile(first_frame=1), frames="1-4", threads=2)
    rc, _, err = cli("run", SVGF, "--input", scene["noisy"], "--output", out_cli,
                     "--frames", "1-4", "--threads", "2")
    assert rc == 0, err
    result = kestrel.compare(out_py, out_cli)
    assert len(result["frames"]) == 4
    assert all(f["relMse"] == 0 for f in result["frames"])


def test_interpreter_lock_is_released_while_cpp_runs(scene):
    c, _ = compiled_svgf(scene)
    ticks, done = [], threading.Event()

    def tick():
        while not done.is_set():
            ticks.append(time.perf_counter())
            time.sleep(0.001)

    t = threading.Thread(target=tick)
    t.start()
    time.sleep(0.01)
    start = time.perf_counter()
    kestrel.run(c, frames="1-4", warmup=0)
    kestrel.run(c, frames="1-4")
    end = time.perf_counter()
    done.set()
    t.join()
    during = [x for x in ticks if start < x < end]
    # With the lock held through the run the other thread could not tick at all.
    assert len(during) >= 3, (len(during), end - start)


def test_signal_handlers_run_between_frames():
    """Ctrl-C stops a run after the frame in progress, not at its end."""
    import os
    import signal

    import numpy as np

    src = kestrel.ArraySource("SignalFeed", {"a": "float3", "b": "float3"})
    one = np.ones((256, 256, 3), np.float32)
    src.set_frame(1, {"a": one, "b": one})
    g = kestrel.Graph()
    g.create_pass("in", "SignalFeed")
    g.create_pass("mix", "Mix")
    g.add_edge("in.a", "mix.a")
    g.add_edge("in.b", "mix.b")
    g.mark_output("mix.color")
    c = g.compile(first_frame=1)

    class Stop(Exception):
        pass

    state = {"running": False, "seen_running": None}

    def handler(signum, frame):
        state["seen_running"] = state["running"]
        raise Stop()

    old = signal.signal(signal.SIGINT, handler)
    try:
        timer = threading.Timer(0.05, lambda: os.kill(os.getpid(), signal.SIGINT))
        timer.start()
        state["running"] = True
        with pytest.raises(Stop):
            kestrel.run(c, frames=[1] * 20000)  # the one frame again and again: ~5 s
        state["running"] = False
        timer.join()
    finally:
        signal.signal(signal.SIGINT, old)
    assert state["seen_running"] is True, "the handler ran only after the run"


def test_resume_replays_history_and_writes_the_rest(scene, tmp_path):
    out = str(tmp_path / "frame_####.exr")
    g = kestrel.load_graph(SVGF, set=["input.path=" + scene["noisy"], "output.path=" + out])
    c = g.compile(first_frame=1)
    kestrel.run(c, frames="1-2")
    run = kestrel.run(c, frames="1-4", resume=True)
    # Frames 1-2 are on disk: replayed without writing (history), then 3-4 written.
    assert [(f["frame"], f["written"]) for f in run.frames] == \
        [(1, False), (2, False), (3, True), (4, True)]


def test_cut_resets_history_as_a_fresh_start(scene):
    c, port = compiled_svgf(scene)
    cut = kestrel.run(c, frames="1-3", cuts=[3]).output(port)
    fresh = kestrel.run(c, frames=[3]).output(port)
    carried = kestrel.run(c, frames="1-3").output(port)
    np.testing.assert_array_equal(cut, fresh)
    assert not np.array_equal(cut, carried)


def test_svgf_on_a_blender_render():
    """The issue's user story on real data: svgf.json over a Blender Cycles sequence, the
    result read as arrays and measured against the 512-spp reference."""
    import os
    import pathlib

    shared = pathlib.Path(os.environ.get("KESTREL_SHARED_DIR", "../shared")) / "data"
    room = shared / "blender-sample-room"
    if not (room / "noisy" / "frame_0001.exr").is_file():
        pytest.skip(f"no Blender sample room in {shared}")
    g = kestrel.load_graph(SVGF, set=[f"input.path={room}/noisy/frame_####.exr"])
    port = in_memory(g)
    errors = []

    def progress(frame):
        ref = kestrel.read_exr(f"{room}/ref/frame_{frame.frame:04d}.exr")
        errors.append(kestrel.compare_images(frame.output(port), ref)["psnr"])

    kestrel.run(g.compile(first_frame=1), frames="1-4", progress=progress)
    noisy = kestrel.compare(f"{room}/noisy/frame_####.exr", f"{room}/ref/frame_####.exr",
                            frames="1-4")
    assert len(errors) == 4
    # Denoised beats the 1-spp input by a wide margin on every frame.
    assert all(e > f["psnr"] + 10 for e, f in zip(errors, noisy["frames"]))


def test_planes_are_views_that_keep_the_run_alive(scene):
    c, port = compiled_svgf(scene)
    run = kestrel.run(c, frames="1-2")
    copy = run.output(port)
    planes = run.planes(port)
    assert len(planes) == 3 and planes[0].shape == (27, 48)
    assert not planes[0].flags.owndata and not planes[0].flags.writeable
    np.testing.assert_array_equal(np.stack(planes, axis=-1), copy)
    del run, c
    gc.collect()
    # Another run's memory comes and goes; the views' run (their base) is alive, its memory too.
    kestrel.run(compiled_svgf(scene, "*.sigmaL=1")[0], frames="1-2")
    gc.collect()
    np.testing.assert_array_equal(np.stack(planes, axis=-1), copy)


def test_one_run_of_a_compiled_graph_at_a_time(scene):
    c, _ = compiled_svgf(scene)
    started, release = threading.Event(), threading.Event()

    def hold(frame):
        started.set()
        release.wait(10)  # the lock is free while waiting

    t = threading.Thread(target=lambda: kestrel.run(c, frames="1-2", progress=hold))
    t.start()
    try:
        assert started.wait(10)
        with pytest.raises(kestrel.Error, match="running in another thread"):
            kestrel.run(c, frames="1-2")
        # Another compiled graph of the same file runs meanwhile.
        assert len(kestrel.run(compiled_svgf(scene)[0], frames="1-2").frames) == 2
    finally:
        release.set()
        t.join()
    assert len(kestrel.run(c, frames="1-2").frames) == 2
