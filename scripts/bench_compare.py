#!/usr/bin/env python3
"""Run polarid's throughput examples and scripts/bench/baselines.py side by side and
print each figure and the ratio polarid/baseline against the issue-7 and issue-18
targets. Called by scripts/bench_compare.sh (which sets up the venv and builds the
examples).

The fit figures compare polarid.fit_nk with the numpy batched LM at its best chunk
size (10^5 or 10^6 pixels), in one process (scripts/bench/fit_nk.py, issue 18).
The DoFP figures (issue 18) come from scripts/bench/dofp.py, which times polarid's
Python API and polanalyser / OpenCV interleaved in one process: it runs in the
interpreter of --polarid-python (default: $POLARID_PYTHON, else .venv-test/bin/python,
the environment scripts/test_python.sh installs polarid into, else this interpreter),
which needs polarid, polanalyser and OpenCV (and numpy for fit_nk.py)."""
import argparse
import json
import os
import re
import subprocess
import sys


# OpenBLAS tuning variables of the host break the pinned numpy of the venvs.
ENV = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_CORETYPE", "OPENBLAS_L2_SIZE")}


def run(cmd):
    print("$ " + " ".join(cmd), file=sys.stderr, flush=True)
    return subprocess.run(cmd, check=True, capture_output=True, text=True, env=ENV).stdout


def polarid_python(arg):
    """The interpreter for scripts/bench/dofp.py (module docstring)."""
    if arg:
        return arg
    if os.environ.get("POLARID_PYTHON"):
        return os.environ["POLARID_PYTHON"]
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    venv = os.path.join(root, ".venv-test", "bin", "python")
    return venv if os.path.exists(venv) else sys.executable


def last_json(text):
    for line in reversed(text.strip().splitlines()):
        line = line.strip()
        if line.startswith("{"):
            return json.loads(line)
    raise ValueError("no JSON line in output:\n" + text)


def find(d, keys):
    """First value of any of `keys` found anywhere in nested dict d."""
    if isinstance(d, dict):
        for k in keys:
            if k in d and isinstance(d[k], (int, float)):
                return float(d[k])
        for v in d.values():
            r = find(v, keys)
            if r is not None:
                return r
    return None


def row(name, ours, base, target, unit):
    ratio = ours / base if base else float("nan")
    ok = "PASS" if target is not None and ratio >= target else ("----" if target is None else "FAIL")
    tgt = f">= {target:g}x" if target is not None else ""
    print(f"{name:<44} {ours:>12.1f} {base:>12.1f} {unit:<10} {ratio:>9.1f}x {tgt:>9} {ok}")
    return ratio


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--baselines", required=True)
    ap.add_argument("--target-dir", required=True)
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--polarid-python", help="interpreter with polarid, polanalyser and OpenCV for the DoFP figures")
    a = ap.parse_args()
    py = sys.executable
    reps = "3" if a.quick else "5"
    loop_pixels = "500" if a.quick else "2000"
    fit_pixels = "200000" if a.quick else "1000000"

    # --- Stokes
    st = last_json(run([py, a.baselines, "stokes", "--repeats", reps]))["results"]
    out = run([os.path.join(a.target_dir, "stokes_throughput")])
    m = re.search(r"stokes\+dolp\+aolp.*?([0-9.]+) Mpixel/s", out)
    ours_stokes = float(m.group(1)) if m else float("nan")
    m = re.search(r"bilinear demosaic.*?([0-9.]+) Mpixel/s", out)
    ours_demosaic = float(m.group(1)) if m else float("nan")

    # --- DoFP through the Python API, interleaved with polanalyser / OpenCV
    dofp_script = os.path.join(os.path.dirname(os.path.abspath(a.baselines)), "dofp.py")
    pp = polarid_python(a.polarid_python)
    try:
        dofp = last_json(run([pp, dofp_script, "--rounds", "3" if a.quick else "5"]))
    except (subprocess.CalledProcessError, ValueError, OSError) as e:
        dofp = None
        err = getattr(e, "stderr", None) or str(e)
        print(f"(DoFP figures not measured: {pp} {dofp_script} failed: {err.strip().splitlines()[-1:]})",
              file=sys.stderr)
    dofp_rust = None
    dofp_exe = os.path.join(a.target_dir, "dofp_throughput")
    if os.path.exists(dofp_exe):
        dofp_rust = last_json(run([dofp_exe, "--repeats", reps]))

    # --- Colour polarization (issue 17): raw colour mosaic -> per-band Stokes, DoLP, AoLP,
    # polarid's fused kernel (Rust example) against polanalyser on the same frame
    colour = None
    colour_exe = os.path.join(a.target_dir, "colour_throughput")
    if os.path.exists(colour_exe):
        colour_script = os.path.join(os.path.dirname(os.path.abspath(a.baselines)), "colour.py")
        try:
            colour = last_json(run([pp, colour_script, "--exe", colour_exe,
                                    "--rounds", "2" if a.quick else "3"]))
        except (subprocess.CalledProcessError, ValueError, OSError) as e:
            err = getattr(e, "stderr", None) or str(e)
            print(f"(colour figures not measured: {colour_script} failed: {err.strip().splitlines()[-1:]})",
                  file=sys.stderr)
    else:
        print(f"(no {colour_exe}: colour figures not measured)", file=sys.stderr)

    # --- Fits: polarid.fit_nk against the numpy batched LM at its best chunk size (10^5
    # or 10^6 pixels), in one process (scripts/bench/fit_nk.py); the scipy loop; the Rust
    # fit_throughput example for reference.
    fit_script = os.path.join(os.path.dirname(os.path.abspath(a.baselines)), "fit_nk.py")
    try:
        fitnk = last_json(run([pp, fit_script, "--pixels", "1000000", "--chunks", "100000,1000000",
                               "--repeats", reps]))
    except (subprocess.CalledProcessError, ValueError, OSError) as e:
        fitnk = None
        err = getattr(e, "stderr", None) or str(e)
        print(f"(fit_nk figures not measured: {pp} {fit_script} failed: {err.strip().splitlines()[-1:]})",
              file=sys.stderr)
    fv = None
    if fitnk is None:
        fv = {c: last_json(run([py, a.baselines, "fit-vec", "--pixels", "1000000", "--chunk", c]))["results"]
              for c in ("100000", "1000000")}
    fl = last_json(run([py, a.baselines, "fit-loop", "--pixels", loop_pixels]))["results"]
    fl_best = max(fl.values(), key=lambda r: r["fits_per_s"])
    fit_exe = os.path.join(a.target_dir, "fit_throughput")
    ours_fit = None
    if os.path.exists(fit_exe):
        ours_fit = last_json(run([fit_exe, "--pixels", fit_pixels, "--threads", str(os.cpu_count() or 2), "--seed", "1"]))

    print()
    print(f"{'figure':<44} {'polarid':>12} {'baseline':>12} {'unit':<10} {'ratio':>10} {'target':>9}")
    row("Stokes+DoLP+AoLP 2048x2448 vs polanalyser", ours_stokes,
        st["polanalyser_stokes_dolp_aolp"]["mpix_per_s"], 20, "Mpixel/s")
    row("Stokes+DoLP+AoLP vs numpy float32", ours_stokes,
        st["numpy_f32_stokes_dolp_aolp"]["mpix_per_s"], None, "Mpixel/s")
    row("DoFP demosaic vs polanalyser", ours_demosaic,
        st["polanalyser_demosaicing_mono"]["mpix_per_s"], None, "Mpixel/s")
    if dofp is not None:
        r = dofp["results"]
        mp = lambda k: r[k]["mpix_per_s"]  # noqa: E731
        # one process, interleaved rounds, best of each (scripts/bench/dofp.py)
        row("DoFP raw->DoLP+AoLP vs polanalyser (Python)", mp("polarid_dofp_dolp_aolp"),
            mp("pa_demosaic_stokes_dolp_aolp"), 20, "Mpixel/s")
        row("  same, into reused arrays (out=)", mp("polarid_dofp_dolp_aolp_out"),
            mp("pa_demosaic_stokes_dolp_aolp"), None, "Mpixel/s")
        row("  unfused demosaic, then dolp_aolp", mp("polarid_demosaic_then_dolp_aolp"),
            mp("pa_demosaic_stokes_dolp_aolp"), None, "Mpixel/s")
        # each at its best settings: the faster of its variants in this run
        best = lambda *ks: max(mp(k) for k in ks)  # noqa: E731
        row("bilinear demosaic vs OpenCV, best settings",
            best("polarid_demosaic_u16_out", "polarid_demosaic_u16", "polarid_demosaic_f32"),
            best("cv2_demosaic", "cv2_demosaic_dst"), 2, "Mpixel/s")
        row("  new arrays, uint16 vs OpenCV", mp("polarid_demosaic_u16"),
            mp("cv2_demosaic"), None, "Mpixel/s")
        row("  new arrays, float32 vs OpenCV", mp("polarid_demosaic_f32"),
            mp("cv2_demosaic"), None, "Mpixel/s")
        row("  float32 vs polanalyser demosaicing", mp("polarid_demosaic_f32"),
            mp("pa_demosaicing"), None, "Mpixel/s")
        checks = (dofp["check_demosaic_u16_equals_polanalyser"], dofp["check_max_abs_dolp_diff"])
        print(f"DoFP checks: uint16 demosaic == polanalyser's: {checks[0]}; "
              f"max |DoLP - polanalyser's| {checks[1]:.2e}; load average {dofp['env']['loadavg_1min']:.1f}")
    if dofp_rust is not None:
        print("polarid dofp_throughput (Rust, reused buffers): " + json.dumps(dofp_rust))
    if colour is not None:
        row("colour raw->per-band Stokes+DoLP+AoLP vs pa", colour["polarid_colour_bilinear"]["mpix_per_s"],
            colour["pa_demosaic_stokes_dolp_aolp"]["mpix_per_s"], 20, "Mpixel/s")
        print("colour (scripts/bench/colour.py): " + json.dumps(colour))
    if ours_fit is None:
        print(f"(no {fit_exe}: polarid fit throughput not measured)")
        print(f"fit-vec  {fv['fits_per_s']:.0f} fits/s, global-optimum rate {fv['frac_cost_le_truth']:.4f}")
        print(f"fit-loop {fl_best['fits_per_s']:.0f} fits/s, global-optimum rate {fl_best['frac_cost_le_truth']:.4f}")

    if fitnk is not None:
        nb = fitnk["numpy"][str(fitnk["numpy_best_chunk"])]
        row(f"fit_nk vs numpy batched LM, best chunk ({fitnk['numpy_best_chunk']:.0e})",
            fitnk["polarid"]["fits_per_s"], nb["fits_per_s"], 50, "fits/s")
        for c, r in fitnk["numpy"].items():
            print(f"  numpy chunk {int(c):>8}: {r['fits_per_s']:>10.0f} fits/s, "
                  f"global-optimum rate {r['frac_cost_le_truth']:.4f}")
        rate, base_rate = fitnk["polarid"]["frac_cost_le_truth"], nb["frac_cost_le_truth"]
        print(f"global-optimum rate: fit_nk {rate:.4f} vs numpy (best chunk) {base_rate:.4f}  "
              f"{'PASS' if rate >= base_rate else 'FAIL'}")
        row("fit_nk vs scipy loop (fit-loop)", fitnk["polarid"]["fits_per_s"], fl_best["fits_per_s"],
            2000, "fits/s")
        print(f"global-optimum rate: fit_nk {rate:.4f} vs fit-loop {fl_best['frac_cost_le_truth']:.4f}  "
              f"{'PASS' if rate >= fl_best['frac_cost_le_truth'] else 'FAIL'}")
        print(f"fit_nk: float32 input {fitnk['polarid']['seconds_float32_input']:.3f} s, all-invalid stack "
              f"(no fitting) {fitnk['polarid']['seconds_all_invalid']:.3f} s, best "
              f"{fitnk['polarid']['seconds_best']:.3f} s for {fitnk['pixels']} pixels; load average "
              f"{fitnk['env']['loadavg_1min_start']} -> {fitnk['env']['loadavg_1min_end']}")
        base_fps = nb["fits_per_s"]
    else:
        best_c = max(fv, key=lambda c: fv[c]["fits_per_s"])
        base_fps = fv[best_c]["fits_per_s"]
        for c, r in fv.items():
            print(f"fit-vec chunk {c}: {r['fits_per_s']:.0f} fits/s, global-optimum rate {r['frac_cost_le_truth']:.4f}")
        print(f"fit-loop {fl_best['fits_per_s']:.0f} fits/s, global-optimum rate {fl_best['frac_cost_le_truth']:.4f}")
    if ours_fit is None:
        print(f"(no {fit_exe}: polarid fit throughput (Rust) not measured)")
    else:
        # The Rust example: the fit without Python, on all cores (reference).
        res = ours_fit.get("results", {})
        fps = (res.get("multi_thread") or {}).get("fits_per_s") or find(
            ours_fit, ["fits_per_s", "fits_per_second"])
        single = (res.get("single_thread") or {}).get("fits_per_s")
        if single is not None:
            print(f"polarid fits/s (Rust fit_throughput): {fps:.0f} on all cores, {single:.0f} on one thread")
        row("Rust fit_batch vs numpy batched LM, best chunk", fps, base_fps, None, "fits/s")
        print("polarid fit_throughput: " + json.dumps(ours_fit))
    print("env: " + json.dumps(last_json(json.dumps({"cpus": os.cpu_count()}))))


if __name__ == "__main__":
    main()
