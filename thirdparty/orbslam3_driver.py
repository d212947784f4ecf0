"""ORB-SLAM3's side of the ORB-SLAM3 agent: a separate program that runs ORB-SLAM3 (GPL-3.0, through the
``pyorbslam3`` wheel) and answers over its standard input and output.

This is the only file of the project that imports ``pyorbslam3``, and it is never imported: the agent
(:mod:`thirdparty.orbslam3`) starts it as ``python orbslam3_driver.py`` and exchanges only data with it (images in,
poses out), so ORB-SLAM3 never runs in our process. It needs nothing of ours: numpy and pyorbslam3 only.

The protocol, one request at a time: a request is one JSON line on stdin, followed by ``nbytes`` raw bytes where the
request says so; the answer is one JSON line on stdout (``{"error": "..."}`` when the request failed).

- ``{"cmd": "init", "vocabulary": PATH, "settings": PATH}`` -> ``{"ok": true, "seconds": load time}``: builds the
  monocular system (no viewer).
- ``{"cmd": "track", "timestamp": s, "height": H, "width": W, "nbytes": H*W*3, "settle_s": S}`` + the RGB bytes ->
  ``{"state": "OK" | "NOT_INITIALIZED" | "RECENTLY_LOST" | "LOST" | ..., "pose_valid": bool, "pose_wc": 16 floats
  (row-major camera-to-world, ORB-SLAM3's camera axes = OpenCV's) or null, "points": tracked map points,
  "seconds": the track call's time, "settle_seconds": the wait after it}``. With ``settle_s`` > 0 the answer waits,
  at most that long, until ORB-SLAM3's other threads (local mapping, loop closing) are idle (:func:`settle`).
- ``{"cmd": "finish", "keyframes": PATH}`` -> ``{"ok": true}``: stops ORB-SLAM3's threads and writes its key-frame
  trajectory (TUM format) to PATH. The program exits when its stdin closes.

ORB-SLAM3 prints to stdout; the program moves that to stderr, keeping stdout for the answers.
"""

from __future__ import annotations

import json
import os
import sys
import threading
import time

IDLE_SAMPLES = 3  # consecutive looks at ORB-SLAM3's threads that must find none of them running
IDLE_INTERVAL_S = 0.002  # seconds between two looks


def running_threads(own: int) -> int | None:
    """How many threads of this process other than ``own`` (a native thread id) are running or runnable (state R
    in ``/proc/self/task/<tid>/stat``: a thread waiting for a core counts, however loaded the machine); None where
    ``/proc`` cannot be read."""
    try:
        tasks = os.listdir("/proc/self/task")
    except OSError:
        return None
    running = 0
    for tid in tasks:
        if int(tid) == own:
            continue
        try:
            with open(f"/proc/self/task/{tid}/stat", "rb") as f:
                stat = f.read()
        except OSError:  # the thread ended meanwhile
            continue
        running += stat[stat.rfind(b")") + 2:stat.rfind(b")") + 3] == b"R"
    return running


def settle(limit_s: float) -> float:
    """Wait until ORB-SLAM3's own threads (local mapping, loop closing; everything but this one) are idle, i.e.
    none running in :data:`IDLE_SAMPLES` looks :data:`IDLE_INTERVAL_S` apart, or ``limit_s`` seconds have passed;
    returns the seconds waited. This gives the mapping threads the time between frames that ORB-SLAM3's TUM example
    gives them by feeding frames at the camera's rate on a machine fast enough to keep up, whatever the load of this
    one. Without ``/proc`` it does not wait."""
    own, t0, idle = threading.get_native_id(), time.perf_counter(), 0
    while idle < IDLE_SAMPLES and time.perf_counter() - t0 < limit_s:
        running = running_threads(own)
        if running is None:
            break
        idle = idle + 1 if running == 0 else 0
        time.sleep(IDLE_INTERVAL_S)
    return time.perf_counter() - t0


def main() -> int:
    """Serve requests until stdin closes."""
    answers = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(2, 1)  # ORB-SLAM3's std::cout (and any print) goes to stderr from here on
    sys.stdout = sys.stderr
    requests = sys.stdin.buffer
    slam = None

    import numpy as np

    while True:
        line = requests.readline()
        if not line:
            break
        try:
            req = json.loads(line)
            payload = requests.read(int(req["nbytes"])) if req.get("nbytes") else b""
            cmd = req.get("cmd")
            if cmd == "init":
                import pyorbslam3

                t0 = time.perf_counter()
                slam = pyorbslam3.Slam(req["vocabulary"], req["settings"], pyorbslam3.Sensor.MONOCULAR,
                                       use_viewer=False)
                answer: dict = {"ok": True, "seconds": time.perf_counter() - t0}
            elif cmd == "track":
                if slam is None:
                    raise RuntimeError("track before init")
                h, w = int(req["height"]), int(req["width"])
                image = np.frombuffer(payload, dtype=np.uint8).reshape(h, w, 3)
                t0 = time.perf_counter()
                res = slam.track_monocular(image, float(req["timestamp"]))
                seconds = time.perf_counter() - t0
                settled = settle(float(req["settle_s"])) if req.get("settle_s") else 0.0
                pose = None
                if res.pose_valid and res.pose_wc is not None:
                    pose = [float(v) for v in np.asarray(res.pose_wc, dtype=np.float64).reshape(-1)]
                answer = {"state": res.state.name, "pose_valid": bool(res.pose_valid), "pose_wc": pose,
                          "points": int(res.num_tracked_points), "seconds": seconds, "settle_seconds": settled}
            elif cmd == "finish":
                if slam is not None:
                    slam.shutdown()
                    if req.get("keyframes"):
                        slam.save_keyframe_trajectory_tum(str(req["keyframes"]))
                slam = None
                answer = {"ok": True}
            else:
                raise ValueError(f"unknown command {cmd!r}")
        except Exception as exc:  # noqa: BLE001 - every failure is answered, the agent raises it
            answer = {"error": f"{type(exc).__name__}: {exc}"}
        answers.write(json.dumps(answer) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
