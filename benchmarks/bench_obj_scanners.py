"""Issue 45: the first OBJ read in a fresh process, scan_bulk alone (old) against scan_plain (new), interleaved.

    python benchmarks/bench_obj_scanners.py FILE.obj [FILE.obj ...]   (e.g. bench_scaling.py write_obj heightfields)
"""
# interleaved, fresh process per read: first read in a process, old (scan_bulk) vs new (scan_plain)
import subprocess, sys, statistics
code = """
import sys, time, resource
import warp_spt.io.obj_bulk as ob
from warp_spt.io.obj import load_obj
if sys.argv[2] == 'old': ob.scan_plain = lambda d, p: None
t = time.perf_counter(); load_obj(sys.argv[1]); print(time.perf_counter() - t, resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
"""
for f in sys.argv[1:]:
    res = {"old": [], "new": []}
    for _ in range(3):
        for k in ("old", "new"):
            out = subprocess.run([sys.executable, "-c", code, f, k], capture_output=True, text=True).stdout.split()
            res[k].append((float(out[0]), float(out[1])))
    for k, v in res.items():
        print(f, k, "median s", round(statistics.median(x for x, _ in v), 3), "peak MB", round(max(m for _, m in v)))
    print("ratio old/new", statistics.median(o[0] / n[0] for o, n in zip(res["old"], res["new"])))
