#!/usr/bin/env python3
"""Equal-time runs of the room for docs/sampling.md (issue 22): wavetrace's independent and
Sobol samplers at fixed spp, wavetrace adaptive, and Mitsuba 3 (box filter, spp chosen from
its measured speed to fill the budget), alternating arm by arm so that a change in the
machine's load falls on every arm alike. Prints one line per run, then the medians.

    python3 tools/equal_time_room.py REFERENCE.exr [--budgets 4 8 16] [--repeats 3] \
        [--threshold 0.02] [--no-mitsuba] [--mitsuba-filter box|gaussian] \
        [--mitsuba-reference MITSUBA_REFERENCE.exr]

Needs `cargo build --release --features examples --example equal_time` (or the dev profile with --profile debug)
and, for Mitsuba, `python3 -m pip install mitsuba`. Mitsuba's fastest CPU variant,
`llvm_ad_rgb` (the default here), needs LLVM's shared library at version 17 or later (15
and 16 fail to select `fminimum`): on Debian 12 `apt-get install libllvm19` and
`DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so`.
"""

import argparse
import re
import statistics
import subprocess
import sys
import time


def wavetrace(example, reference, budget, seed, extra):
    cmd = [example, "scenes/room.toml", "--reference", reference, "--time", f"{budget}s",
           "--seed", str(seed)] + extra
    out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
    line = next(l for l in out.splitlines() if l.startswith("seed "))
    m = re.search(r"([\d.]+) spp, [\d.]+ rays per pixel in ([\d.]+) s: rmse ([\d.]+).*relative mse ([\d.]+), top 1% "
                  r"of pixels hold ([\d.]+)%", line)
    spp, seconds, rmse, rel, top = map(float, m.groups())
    return {"spp": spp, "s": seconds, "rmse": rmse, "rel": rel, "top": top}


def mitsuba(reference, spp, seed, size, out, variant, pixel_filter):
    r = subprocess.run([sys.executable, "tools/mitsuba_room.py", "render", "scenes/room.toml",
                        out, "--spp", str(spp), "--seed", str(seed), "--size", str(size),
                        "--filter", pixel_filter, "--variant", variant],
                       capture_output=True, text=True, check=True).stdout
    seconds = float(re.search(r"([\d.]+) s$", r.strip()).group(1))
    e = subprocess.run([sys.executable, "tools/mitsuba_room.py", "error", reference, out,
                        "--variant", "scalar_rgb"], capture_output=True, text=True,
                       check=True).stdout
    m = re.search(r"mse ([\d.]+), relative mse ([\d.]+), top 1% of pixels hold ([\d.]+)%", e)
    mse, rel, top = map(float, m.groups())
    return {"spp": float(spp), "s": seconds, "rmse": mse ** 0.5, "rel": rel, "top": top}


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("reference")
    p.add_argument("--budgets", type=float, nargs="+", default=[4, 8, 16])
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--threshold", type=float, default=0.02)
    p.add_argument("--profile", default="release")
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--no-mitsuba", action="store_true")
    p.add_argument("--mitsuba-variant", default="llvm_ad_rgb")
    p.add_argument("--mitsuba-filter", choices=["box", "gaussian"], default="box",
                   help="Mitsuba's pixel filter (its default is gaussian; wavetrace's is box)")
    p.add_argument("--mitsuba-reference",
                   help="Mitsuba's own reference (same filter); default: REFERENCE")
    p.add_argument("--arms", nargs="+", default=["independent", "sobol", "adaptive"],
                   help="wavetrace arms to run: independent, sobol, adaptive, no-connections")
    p.add_argument("--scratch", default="target/mitsuba_equal_time.exr")
    args = p.parse_args()
    example = f"target/{args.profile}/examples/equal_time"
    arms = {
        "independent": ["--sampler", "independent"],
        "sobol": ["--sampler", "sobol"],  # the default estimator (merging included)
        "adaptive": ["--sampler", "independent", "--noise-threshold", str(args.threshold)],
        # The light paths without their connections to camera vertices (the code before them).
        "no-connections": ["--sampler", "independent", "--no-caustic-connections"],
    }
    arms = {name: arms[name] for name in args.arms}
    mitsuba_reference = args.mitsuba_reference or args.reference
    results = {}
    mitsuba_rate = None  # samples per pixel per second, from the last Mitsuba run
    for repeat in range(args.repeats):
        for budget in args.budgets:
            seed = 100 + repeat
            for name, extra in arms.items():
                r = wavetrace(example, args.reference, budget, seed, extra)
                results.setdefault((name, budget), []).append(r)
                print(f"{budget:g} s {name} seed {seed}: {r}", flush=True)
            if not args.no_mitsuba:
                if mitsuba_rate is None:
                    probe = mitsuba(mitsuba_reference, 2, seed, args.size, args.scratch,
                                    args.mitsuba_variant, args.mitsuba_filter)
                    mitsuba_rate = 2 / probe["s"]
                spp = max(1, int(budget * mitsuba_rate))
                r = mitsuba(mitsuba_reference, spp, seed, args.size, args.scratch,
                            args.mitsuba_variant, args.mitsuba_filter)
                mitsuba_rate = r["spp"] / r["s"]
                results.setdefault((f"mitsuba {args.mitsuba_variant}", budget), []).append(r)
                print(f"{budget:g} s mitsuba seed {seed}: {r}", flush=True)
    print("\nmedians:")
    print("| budget | arm | spp | s | RMSE | rel. MSE | top 1% |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for (name, budget), runs in sorted(results.items(), key=lambda kv: (kv[0][1], kv[0][0])):
        med = {k: statistics.median(r[k] for r in runs) for k in runs[0]}
        print(f"| {budget:g} s | {name} | {med['spp']:.1f} | {med['s']:.2f} | {med['rmse']:.4f} "
              f"| {med['rel']:.4f} | {med['top']:.1f}% |")


if __name__ == "__main__":
    sys.exit(main())
