#!/usr/bin/env python3
"""Whole-process timing of `truepos fit sphere FILE --json` against numpy+scipy and
scikit-spatial on the same 1,000,000-point CSV. Run through scripts/bench_fit.sh (which makes
the virtual environment); never run by CI.

Usage: bench_fit.py gen FILE N            write a noisy sphere CSV (x_mm,y_mm,z_mm)
       bench_fit.py scipy FILE            fit with scipy.optimize.least_squares, print JSON
       bench_fit.py skspatial FILE        fit with skspatial Sphere.best_fit, print JSON
       bench_fit.py time TRUEPOS FILE REPS   time all three as whole processes
"""
import json
import statistics
import subprocess
import sys
import time


def gen(path, n):
    import numpy as np

    rng = np.random.default_rng(1)
    c = np.array([120.5, -40.25, 310.0])
    r = 12.7
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    d = d[d[:, 2] > -0.3]  # a probed sphere: the stem hides the bottom
    d = np.concatenate([d, d])[:n]
    p = c + d * (r + rng.normal(scale=0.002, size=(len(d), 1)))
    np.savetxt(path, p, fmt="%.6f", delimiter=",", header="x_mm,y_mm,z_mm", comments="")


def load(path):
    import numpy as np

    return np.loadtxt(path, delimiter=",", skiprows=1)


def fit_scipy(path):
    import numpy as np
    from scipy.optimize import least_squares

    p = load(path)
    c0 = p.mean(axis=0)
    r0 = np.linalg.norm(p - c0, axis=1).mean()

    def fun(x):
        return np.linalg.norm(p - x[:3], axis=1) - x[3]

    def jac(x):
        v = p - x[:3]
        d = np.linalg.norm(v, axis=1)[:, None]
        return np.hstack([-v / d, -np.ones((len(p), 1))])

    res = least_squares(fun, np.r_[c0, r0], jac=jac, method="lm")
    print(json.dumps({"center_mm": res.x[:3].tolist(), "radius_mm": float(res.x[3])}))


def fit_skspatial(path):
    from skspatial.objects import Sphere

    p = load(path)
    s = Sphere.best_fit(p)
    print(json.dumps({"center_mm": list(map(float, s.point)), "radius_mm": float(s.radius)}))


def timed(cmd, reps):
    out, ts = None, []
    for _ in range(reps):
        t0 = time.perf_counter()
        r = subprocess.run(cmd, check=True, capture_output=True, text=True)
        ts.append(time.perf_counter() - t0)
        out = json.loads(r.stdout)
    return ts, out


def bench(truepos, path, reps):
    py = sys.executable
    me = __file__
    runs = {
        "truepos": [truepos, "fit", "sphere", path, "--json"],
        "scipy least_squares": [py, me, "scipy", path],
        "scikit-spatial Sphere.best_fit": [py, me, "skspatial", path],
    }
    results = {}
    for name, cmd in runs.items():
        ts, out = timed(cmd, reps)
        results[name] = (ts, out)
        print(f"{name:32s} median {statistics.median(ts):7.3f} s  min {min(ts):7.3f} s  "
              f"radius {out['radius_mm']:.9f}  centre {', '.join(f'{v:.9f}' for v in out['center_mm'])}")
    t = statistics.median(results["truepos"][0])
    for name in list(runs)[1:]:
        print(f"ratio {name} / truepos: {statistics.median(results[name][0]) / t:.1f}x")


if __name__ == "__main__":
    cmd = sys.argv[1]
    if cmd == "gen":
        gen(sys.argv[2], int(sys.argv[3]))
    elif cmd == "scipy":
        fit_scipy(sys.argv[2])
    elif cmd == "skspatial":
        fit_skspatial(sys.argv[2])
    elif cmd == "time":
        bench(sys.argv[2], sys.argv[3], int(sys.argv[4]))
    else:
        sys.exit(__doc__)
