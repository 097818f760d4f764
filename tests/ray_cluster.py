"""Run a sweep on a two-node Ray cluster inside a private network and PID namespace (see tests/test_sweep.py).

    unshare --net --pid --fork --mount-proc python tests/ray_cluster.py SPEC OUT STORAGE REPORT.json

Inside: loopback up (the only interface, so all traffic stays on it); a head and a worker node of one CPU each
(token authentication on, with a token made here); a client with another token refused; the sweep started against
the head, killed (SIGKILL) once its first trial has finished, then started again with the same command and run to
the end; the cluster stopped. REPORT.json gets what happened. When this process (the namespace's first) exits,
the kernel ends every process left in the namespace.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PORT = 6390


def main() -> int:
    spec, out, storage, report = sys.argv[1:5]
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    bindir = Path(sys.executable).parent
    ray = str(bindir / "ray") if (bindir / "ray").exists() else "ray"
    temp = tempfile.mkdtemp(prefix="ssr", dir="/tmp")  # unix socket paths must stay short
    env = {**os.environ, "RAY_AUTH_MODE": "token", "RAY_AUTH_TOKEN": secrets.token_hex(16),
           "RAY_USAGE_STATS_ENABLED": "0", "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT),
                                                                                       os.environ.get("PYTHONPATH")]))}
    node = ["--node-ip-address=127.0.0.1", "--num-cpus=1", f"--temp-dir={temp}"]
    info: dict = {"interfaces": subprocess.run(["ip", "-o", "addr"], capture_output=True, text=True).stdout}
    t0 = time.time()
    try:
        subprocess.run([ray, "start", "--head", f"--port={PORT}", "--include-dashboard=false",
                        "--disable-usage-stats", *node], env=env, check=True, capture_output=True)
        subprocess.run([ray, "start", f"--address=127.0.0.1:{PORT}", *node], env=env, check=True, capture_output=True)
        info["cluster_start_s"] = round(time.time() - t0, 1)
        cmd = [sys.executable, str(ROOT / "tools" / "sweep.py"), spec, "--out", out, "--address", f"127.0.0.1:{PORT}",
               "--storage", storage]
        t1 = time.time()  # a client with another token is told so, at once
        wrong = subprocess.run([*cmd, "--dry-run"], env={**env, "RAY_AUTH_TOKEN": secrets.token_hex(16)},
                               capture_output=True, text=True, timeout=120)
        info.update(wrong_token_exit=wrong.returncode, wrong_token_stderr=wrong.stderr[-2000:],
                    wrong_token_s=round(time.time() - t1, 1))
        trials = Path(storage) / Path(out).name / "trials"
        first = subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        deadline = time.time() + 300
        while time.time() < deadline and first.poll() is None and not list(trials.glob("*/result.json")):
            time.sleep(0.2)
        info["finished_at_kill"] = sorted(p.parent.name for p in trials.glob("*/result.json"))
        info["first_exit"] = first.poll()
        first.send_signal(signal.SIGKILL)
        info["first_stderr"] = first.communicate()[1][-3000:]
        info["mtimes_at_kill"] = {p.parent.name: p.stat().st_mtime_ns for p in trials.glob("*/result.json")}
        t1 = time.time()
        second = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=400)
        info.update(second_exit=second.returncode, second_stderr=second.stderr[-3000:],
                    resume_s=round(time.time() - t1, 1))
    finally:
        subprocess.run([ray, "stop", "--force"], env=env, capture_output=True)
        shutil.rmtree(temp, ignore_errors=True)
    info["total_s"] = round(time.time() - t0, 1)
    Path(report).write_text(json.dumps(info, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
