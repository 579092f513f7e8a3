#!/usr/bin/env python3
"""Independent renders of a calibrated bench seen by a COLOUR polarization camera.

A Sony IMX250MYR-type sensor puts a 2x2 polarizer block under each colour of a Bayer
pattern of blocks (a 4x4 period; docs/FORMATS.md, "Colour polarization cameras"). This
script renders the bench of a bench TOML (render_bench.py's format, with every plate's
(n, k) at each band) once per band with render_bench.py's Mitsuba renderer, then
assembles one colour raw mosaic per capture: each pixel takes the ideal polarizer
intensity of its band (the colour of its block) and its angle (its place in the block),
then the camera's shot noise, read noise, dark level and 12-bit quantisation of
render_plates.py. One exposure per capture serves all bands (a real camera's), so the
bands' brightness differs as the plates' reflectances do.

Subcommands (see tools/render/README.md, "Colour camera"):

    render_colour.py render SCENE.toml -o OUTDIR [--color RGGB] [--force]
        renders OUTDIR/bands/band_<nm> (skipped when present, unless --rerender), then
        assembles the colour set (as `assemble`)
    render_colour.py assemble OUTDIR [--color RGGB]
        the colour mosaics, manifests and truth from OUTDIR/bands/band_<nm>
    render_colour.py check OUTDIR [--polarid BIN]
        re-measures the files: per band, the region DoLP of the colour mosaic (numpy
        super-pixels; `polarid stokes --color` with --polarid) against the ideal one and
        eq. (9); with --polarid also the mono path on each band's separated mosaic
        (`polarid measure` + `fit` on separated/manifest_<nm>.toml) against the truth

Output (OUTDIR):

    manifest_colour.toml      calibrated geometry, `bands`, one colour DoFP capture per lamp
    L01/raw.tif ...           the colour raw mosaics (uint16, 12-bit counts)
    labels.tif                uint8 plate labels (0 background, i + 1 = truth plates[i])
    truth.json, truth_plates.csv
    separated/manifest_<nm>.toml, separated/band_<nm>/L01/raw.tif
                              each band's samples as a half-resolution mono DoFP mosaic
                              (for G the top-right block of the period) with the camera
                              scaled to it: polarid's mono path on the colour data
    bands/band_<nm>/          the per-band mono sets of render_bench.py (ideal Stokes,
                              frames, mono DoFP with their own noise, per-band truth)
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
import tomllib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import render_bench as rb  # noqa: E402
import render_plates as rp  # noqa: E402

ANGLES = rp.ANGLES
DEFAULT_BANDS = {"R": 650.0, "G": 550.0, "B": 450.0}


def parse_bands(spec: str) -> dict:
    out = {}
    for item in spec.split(","):
        k, v = item.split("=")
        out[k.strip().upper()] = float(v)
    return out


def colour_layout(color: str, pattern, h: int, w: int):
    """Per-pixel colour letter index (into `color`) and polarizer angle of a colour DoFP
    mosaic: the 4x4 period holds 2x2 blocks, block (by, bx) of colour color[2 by + bx],
    and in each block the polarizer pattern row by row (docs/FORMATS.md)."""
    yy, xx = np.mgrid[0:h, 0:w]
    block = 2 * ((yy % 4) // 2) + (xx % 4) // 2
    pol = 2 * (yy % 2) + (xx % 2)
    return block, np.asarray(pattern, float)[pol]


def align4(rect):
    """Largest sub-rectangle with x, y, w, h multiples of 4 (whole colour periods)."""
    x, y, w, h = rect
    x4, y4 = -(-x // 4) * 4, -(-y // 4) * 4
    return [int(x4), int(y4), int((x + w - x4) // 4 * 4), int((y + h - y4) // 4 * 4)]


def band_dirs(root: str, bands: dict) -> dict:
    return {wl: os.path.join(root, "bands", f"band_{wl:g}") for wl in sorted(set(bands.values()))}


def _f(x) -> str:
    return repr(float(x))


def _v(v) -> str:
    return "[" + ", ".join(_f(x) for x in v) + "]"


def cmd_render(args):
    bands = parse_bands(args.bands)
    out = os.path.abspath(args.output)
    if os.path.exists(os.path.join(out, "manifest_colour.toml")) and not args.force:
        raise SystemExit(f"{out} holds a colour set (use --force to replace it)")
    os.makedirs(os.path.join(out, "bands"), exist_ok=True)
    times = {}
    for wl, d in band_dirs(out, bands).items():
        if os.path.isfile(os.path.join(d, "truth.json")) and not args.rerender:
            print(f"band {wl:g} nm: reusing {d}")
            continue
        t = time.time()
        ns = argparse.Namespace(bench=args.scene, wavelength=wl, output=d, variant=args.variant, force=True,
                                quiet=args.quiet)
        rb.cmd_render(ns)
        times[f"{wl:g}"] = round(time.time() - t, 1)
    assemble(out, args.color, bands, args.scene, times)


def cmd_assemble(args):
    assemble(os.path.abspath(args.dir), args.color, parse_bands(args.bands), None, {})


def assemble(root: str, color: str, bands: dict, scene_path, band_times: dict):
    t0 = time.time()
    import tifffile

    color = color.upper()
    if len(color) != 4 or any(c not in bands for c in color):
        raise SystemExit(f"--color {color!r}: four letters, each with a band in {bands}")
    dirs = band_dirs(root, bands)
    truths = {}
    for wl, d in dirs.items():
        with open(os.path.join(d, "truth.json")) as f:
            truths[wl] = json.load(f)
    wls = sorted(dirs)
    t_first = truths[wls[0]]
    with open(os.path.join(dirs[wls[0]], "manifest.toml"), "rb") as f:
        man = tomllib.load(f)
    W, H = t_first["image"]["width"], t_first["image"]["height"]
    if W % 4 or H % 4:
        raise SystemExit(f"image {W}x{H}: width and height must be multiples of 4")
    sens = t_first["sensor"]
    b = argparse.Namespace(electrons_per_dn=sens["electrons_per_dn"], read_noise_dn=sens["read_noise_dn"],
                           dark_level=sens["dark_level_dn"], saturation=sens["saturation_dn"])
    pattern = sens["dofp_pattern"]
    labels = tifffile.imread(os.path.join(dirs[wls[0]], "labels.tif"))
    on = labels > 0
    plates = t_first["plates"]
    for wl in wls:
        if [p["name"] for p in truths[wl]["plates"]] != [p["name"] for p in plates]:
            raise SystemExit(f"band {wl:g}: other plates than band {wls[0]:g}")
    regions = {p["name"]: align4(p["region"]) for p in plates}
    block, pol_ang = colour_layout(color, pattern, H, W)
    band_of_block = [bands[c] for c in color]

    # Radiance (Stokes in the bands' common unit: the point lamp's 1 W/sr) per band and capture.
    ncap = len(t_first["captures"])
    caps_out = []
    full = b.saturation - b.dark_level
    stokes = {}
    for j in range(ncap):
        name = t_first["captures"][j]["name"]
        for wl in wls:
            g = truths[wl]["sensor"]["reference_gain_dn_per_radiance"]
            stokes[wl, j] = [tifffile.imread(os.path.join(dirs[wl], "ideal", name, f"{c}.tif")).astype(np.float64) / g
                             for c in ("s0", "s1", "s2")]
    peaks = []
    for j in range(ncap):
        peaks.append(max(float(rp.polarizer(*stokes[wl, j], a)[on].max()) for wl in set(band_of_block) for a in ANGLES))
    gains = [0.7 * full / pk for pk in peaks]
    g_ref = min(gains)
    seed = int(t_first["sensor"]["seed"]) // 1000 * 1000 + 4
    rng = np.random.default_rng(seed)
    tmp_sep = os.path.join(root, "separated.partial")
    shutil.rmtree(tmp_sep, ignore_errors=True)
    first_block = {c: color.index(c) for c in color}
    for j in range(ncap):
        tc = t_first["captures"][j]
        name = tc["name"]
        ideal = np.zeros((H, W))
        for bi in range(4):
            S = stokes[band_of_block[bi], j]
            for a in ANGLES:
                m = (block == bi) & (pol_ang == a)
                ideal[m] = rp.polarizer(S[0][m], S[1][m], S[2][m], a)
        raw = rp.expose(ideal, gains[j], b, rng)
        rp.write_image(os.path.join(root, name, "raw.tif"), raw)
        # Separated mono mosaics: the samples of one block position per band.
        for c, bi in first_block.items():
            by, bx = divmod(bi, 2)
            sub = np.empty((H // 2, W // 2), raw.dtype)
            for dy in (0, 1):
                for dx in (0, 1):
                    sub[dy::2, dx::2] = raw[2 * by + dy::4, 2 * bx + dx::4]
            rp.write_image(os.path.join(tmp_sep, f"band_{bands[c]:g}", name, "raw.tif"), sub)
        cap = {"name": name, "lamp": tc["lamp"], "lamp_spec": tc["lamp_spec"], "gain_dn_per_radiance": gains[j],
               "exposure": gains[j] / g_ref, "brightest_plate_dn": peaks[j] * gains[j], "plates": {}}
        for p in plates:
            x, y, w, h = regions[p["name"]]
            sl = (slice(y, y + h), slice(x, x + w))
            rec = {}
            for wl in wls:
                S = stokes[wl, j]
                m = [float(s[sl].mean()) for s in S]
                dl, al = rp.dolp_aolp(*m) if m[0] > 0 else (float("nan"), float("nan"))
                tb = truths[wl]["captures"][j]["plates"][p["name"]]
                rec[f"{wl:g}"] = {"region_s0_dn": m[0] * gains[j], "region_dolp": dl, "region_aolp_deg": al,
                                  "beta_mean_deg_band_region": tb["beta_mean_deg"],
                                  "center_pixel_dolp_eq9": tb["center_pixel"]["dolp_eq9"],
                                  "center_pixel_beta_deg": tb["center_pixel"]["beta_deg"]}
            cap["plates"][p["name"]] = rec
        caps_out.append(cap)

    # Well lit per band: region S0 >= 100 DN (this set's exposure) in >= 6 captures.
    plates_out = []
    for i, p in enumerate(plates):
        pb = {}
        for wl in wls:
            tp = truths[wl]["plates"][i]
            lit = [c["name"] for c in caps_out if c["plates"][p["name"]][f"{wl:g}"]["region_s0_dn"] >= 100.0]
            pb[f"{wl:g}"] = {"n": tp["n"], "k": tp["k"], "nk_source": tp["nk_source"], "well_lit": len(lit) >= 6,
                             "captures_at_least_100_dn": lit}
        plates_out.append({"name": p["name"], "class": p["class"], "plane": p["plane"], "sigma": p["sigma"],
                           "beckmann_alpha": p["beckmann_alpha"], "label": i + 1, "pixels": p["pixels"],
                           "region": regions[p["name"]], "band_set_region": p["region"], "corners": p["corners"],
                           "bands": pb, "well_lit": all(v["well_lit"] for v in pb.values())})

    # Manifests.
    cam = man["camera"]
    head = [f"dark_level = {b.dark_level:.1f}", f"saturation = {b.saturation:.1f}",
            "bands = { " + ", ".join(f"{c} = {bands[c]:.1f}" for c in sorted(set(color))) + " }",
            "", "[camera]", f"focal_px = {_v(cam['focal_px'])}",
            f"principal_point_px = {_v(cam['principal_point_px'])}", f"position = {_v(cam['position'])}",
            f"look_at = {_v(cam['look_at'])}", f"up = {_v(cam['up'])}"]
    planes = []
    for pl in man["plane"]:
        planes += ["", "[[plane]]", f'name = "{pl["name"]}"', f"point = {_v(pl['point'])}",
                   f"normal = {_v(pl['normal'])}"]
    pat = ", ".join(str(int(a)) for a in pattern)
    lines = ["# polarid capture set rendered by tools/render/render_colour.py (Mitsuba 3, one render per band):",
             f"# colour polarization camera, colour blocks {color}, polarizer blocks [{pat}];",
             "# calibrated geometry (docs/FORMATS.md); ground truth in truth.json"] + head + planes
    for p in plates:
        lines += ["", "[[region]]", f'name = "{p["name"]}"', f"rect = {regions[p['name']]}",
                  f'class = "{p["class"]}"', f'plane = "{p["plane"]}"']
    for c in caps_out:
        lines += ["", "[[capture]]", f'name = "{c["name"]}"', f"source = {{ position = {_v(c['lamp'])} }}",
                  f"exposure = {c['exposure']:.9g}",
                  f'dofp = {{ file = "{c["name"]}/raw.tif", pattern = [{pat}], color = "{color}" }}']
    with open(os.path.join(root, "manifest_colour.toml"), "w") as f:
        f.write("\n".join(lines) + "\n")

    # Separated manifests: band letter c's first block (by, bx); sub-pixel x' holds raw
    # column 4 (x' // 2) + 2 bx + x' % 2, i.e. u = 2 x' + 2 bx - 0.5 (+-0.5): fx' = fx / 2,
    # cx' = (cx - 2 bx + 0.5) / 2 (likewise rows). Regions: raw rect / 2 (multiples of 4).
    fx, fy = cam["focal_px"]
    cx, cy = cam["principal_point_px"]
    for c, bi in first_block.items():
        by, bx = divmod(bi, 2)
        wl = bands[c]
        sl = ["# one band of manifest_colour.toml as a half-resolution mono DoFP mosaic (tools/render/render_colour.py):",
              f"# the {c} samples of block ({by}, {bx}) of each 4x4 period; camera scaled to the sub-mosaic",
              f"dark_level = {b.dark_level:.1f}", f"saturation = {b.saturation:.1f}", f"wavelength_nm = {wl:.1f}",
              "", "[camera]", f"focal_px = {_v([fx / 2, fy / 2])}",
              f"principal_point_px = {_v([(cx - 2 * bx + 0.5) / 2, (cy - 2 * by + 0.5) / 2])}",
              f"position = {_v(cam['position'])}", f"look_at = {_v(cam['look_at'])}", f"up = {_v(cam['up'])}"]
        sl += planes
        for p in plates:
            x, y, w, h = regions[p["name"]]
            sl += ["", "[[region]]", f'name = "{p["name"]}"', f"rect = {[x // 2, y // 2, w // 2, h // 2]}",
                   f'class = "{p["class"]}"', f'plane = "{p["plane"]}"']
        for cp in caps_out:
            sl += ["", "[[capture]]", f'name = "{cp["name"]}"', f"source = {{ position = {_v(cp['lamp'])} }}",
                   f"exposure = {cp['exposure']:.9g}",
                   f'dofp = {{ file = "band_{wl:g}/{cp["name"]}/raw.tif", pattern = [{pat}] }}']
        with open(os.path.join(tmp_sep, f"manifest_{wl:g}.toml"), "w") as f:
            f.write("\n".join(sl) + "\n")
    shutil.rmtree(os.path.join(root, "separated"), ignore_errors=True)
    os.rename(tmp_sep, os.path.join(root, "separated"))
    shutil.copy(os.path.join(dirs[wls[0]], "labels.tif"), os.path.join(root, "labels.tif"))
    if scene_path:
        shutil.copy(scene_path, os.path.join(root, "scene.toml"))

    truth = {
        "set": os.path.basename(root),
        "color": color,
        "dofp_pattern": pattern,
        "bands": {c: bands[c] for c in sorted(set(color))},
        "layout": "4x4 period: 2x2 polarizer blocks (dofp_pattern, row by row) under a 2x2 pattern of colour "
                  "blocks (color, block-row by block-row), docs/FORMATS.md",
        "renderer": {**t_first["renderer"], "bands_rendered_separately": [f"{wl:g}" for wl in wls],
                     "band_render_seconds": {f"{wl:g}": truths[wl]["renderer"]["render_seconds"] for wl in wls},
                     "band_set_total_seconds": band_times},
        "image": t_first["image"],
        "camera": t_first["camera"],
        "planes": t_first["planes"],
        "sensor": {k: v for k, v in sens.items() if k not in ("reference_gain_dn_per_radiance", "seed")}
        | {"exposure_mode": "auto, one gain per capture for all bands: the brightest plate pixel of any band and "
                            "polarizer at 70 % of the range above the dark level",
           "reference_gain_dn_per_radiance": g_ref, "seed": seed},
        "plates": plates_out,
        "labels_file": "labels.tif (uint8: 0 background, i + 1 = plates[i], from ray casting the pixel centres)",
        "separated": {c: {"wavelength_nm": bands[c], "block": list(divmod(bi, 2)),
                          "manifest": f"separated/manifest_{bands[c]:g}.toml"} for c, bi in first_block.items()},
        "checks_per_band": {f"{wl:g}": truths[wl]["checks"] for wl in wls},
        "captures": caps_out,
    }
    with open(os.path.join(root, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    with open(os.path.join(root, "truth_plates.csv"), "w") as f:
        f.write("# per plate and band: (n, k) truth; well_lit = region S0 >= 100 DN in >= 6 captures\n")
        f.write("target,class,wavelength_nm,n,k,sigma,well_lit,region_x,region_y,region_w,region_h\n")
        for p in plates_out:
            for wl, v in p["bands"].items():
                f.write(f"{p['name']},{p['class']},{wl},{v['n']:.10g},{v['k']:.10g},{p['sigma']:g},"
                        f"{str(v['well_lit']).lower()},{','.join(str(q) for q in p['region'])}\n")
    print(f"assembled {root}: {ncap} colour captures {W}x{H} ({color}), {time.time() - t0:.1f} s")
    for p in plates_out:
        print(f"  {p['name']:15s} well lit: " + ", ".join(
            f"{wl} {'yes' if v['well_lit'] else 'NO'} ({len(v['captures_at_least_100_dn'])})" for wl, v in p["bands"].items()))


# ----------------------------------------------------------------------------------------
# check
# ----------------------------------------------------------------------------------------


def superpixel_band(raw, block, pol_ang, bi, dark):
    """One value per 4x4 period of block bi's four polarizer samples: {angle: image}."""
    out = {}
    for a in ANGLES:
        m = (block == bi) & (pol_ang == a)
        H, W = raw.shape
        out[a] = (raw[m].reshape(H // 4, W // 4) - dark)
    return out


def lattice_bilinear(raw, oy, ox):
    """The samples raw[oy::4, ox::4] (one colour block's lattice of one polarizer angle)
    interpolated bilinearly to every pixel (exact for a linear brightness ramp; edges
    clamped)."""
    L = raw[oy::4, ox::4]
    H, W = raw.shape

    def axis(n_out, off, n_lat):
        pos = np.clip((np.arange(n_out) - off) / 4.0, 0, n_lat - 1)
        i0 = np.floor(pos).astype(int)
        i1 = np.minimum(i0 + 1, n_lat - 1)
        return i0, i1, pos - i0

    y0, y1, ty = axis(H, oy, L.shape[0])
    x0, x1, tx = axis(W, ox, L.shape[1])
    rows = L[y0] * (1 - ty)[:, None] + L[y1] * ty[:, None]
    return rows[:, x0] * (1 - tx)[None, :] + rows[:, x1] * tx[None, :]


def bilinear_band(raw, color, pattern, letter, dark):
    """Full-resolution polarizer images {angle: image} of one band: each of its blocks'
    lattices interpolated (lattice_bilinear), the blocks of the same colour averaged."""
    out = {}
    for a_idx, a in enumerate(pattern):
        py, px = divmod(a_idx, 2)
        imgs = [lattice_bilinear(raw, 2 * (bi // 2) + py, 2 * (bi % 2) + px) for bi in range(4) if color[bi] == letter]
        out[int(a)] = sum(imgs) / len(imgs) - dark
    return out


def cmd_check(args):
    root = os.path.abspath(args.dir)
    with open(os.path.join(root, "truth.json")) as f:
        truth = json.load(f)
    with open(os.path.join(root, "manifest_colour.toml"), "rb") as f:
        man = tomllib.load(f)
    color, bands = truth["color"], truth["bands"]
    H, W = truth["image"]["height"], truth["image"]["width"]
    block, pol_ang = colour_layout(color, truth["dofp_pattern"], H, W)
    dark = float(man["dark_level"])
    worst = {"bilinear": 0.0, "z_bilinear": 0.0, "superpixel": 0.0, "z_superpixel": 0.0, "polarid": 0.0, "z_polarid": 0.0, "ideal_vs_eq9_center": 0.0}
    print("per band and capture: region DoLP ideal (from the rendered Stokes), colour mosaic by numpy super-pixels"
          " (SE), numpy bilinear per lattice, polarid stokes --color (bilinear)")
    print(f"{'cap':4s} {'plate':15s} {'nm':>4s} {'S0 DN':>7s} {'ideal':>8s} {'superpx':>8s} {'se':>7s} {'bilinear':>8s} "
          f"{'polarid':>8s}")
    tmp = tempfile.mkdtemp(prefix="colour_check_")
    per_plate = {}
    for cap, mc in zip(truth["captures"], man["capture"]):
        raw = rp.read_image(os.path.join(root, mc["dofp"]["file"]))
        pol = {}
        if args.polarid:
            od = os.path.join(tmp, cap["name"])
            bands_arg = ",".join(f"{c}={v:g}" for c, v in bands.items())
            r = subprocess.run([args.polarid, "stokes", "--dofp", os.path.join(root, mc["dofp"]["file"]), "--color",
                                color, "--bands", bands_arg, "--dark-level", f"{dark:g}", "-o", od, "-q"],
                               capture_output=True, text=True)
            if r.returncode != 0:
                raise SystemExit(f"polarid stokes failed: {r.stderr}")
            for wl in set(bands.values()):
                pol[wl] = [rp.read_image(os.path.join(od, f"{c}_{wl:g}.tif")) for c in ("s0", "s1", "s2")]
        for p in truth["plates"]:
            x, y, w, h = p["region"]
            for c in sorted(set(color), key=lambda c: bands[c]):
                wl = bands[c]
                rec = cap["plates"][p["name"]][f"{wl:g}"]
                bi = color.index(c)
                sp = superpixel_band(raw, block, pol_ang, bi, dark)
                sl = (slice(y // 4, (y + h) // 4), slice(x // 4, (x + w) // 4))
                I = {a: v[sl] for a, v in sp.items()}
                dl, se = rp._dolp_se(0.5 * (I[0] + I[45] + I[90] + I[135]), I[0] - I[90], I[45] - I[135])
                bl = bilinear_band(raw, color, truth["dofp_pattern"], c, dark)
                q = {a: v[y:y + h, x:x + w] for a, v in bl.items()}
                dlb = math.hypot((q[0] - q[90]).mean(), (q[45] - q[135]).mean()) / (
                    0.5 * (q[0] + q[45] + q[90] + q[135]).mean())
                ideal = rec["region_dolp"]
                pd = float("nan")
                if pol:
                    S = [s[y:y + h, x:x + w].mean() for s in pol[wl]]
                    pd = math.hypot(S[1], S[2]) / S[0]
                lit = rec["region_s0_dn"] >= 100
                if lit:
                    acc = per_plate.setdefault((p["name"], wl), [0.0, 0.0, 0.0, 0])
                    acc[0] = max(acc[0], abs(dlb - ideal))
                    acc[1] = max(acc[1], abs(pd - ideal) if pol else float("nan"))
                    acc[2] = max(acc[2], abs(rec["center_pixel_dolp_eq9"] - ideal))
                    acc[3] += 1
                    worst["bilinear"] = max(worst["bilinear"], abs(dlb - ideal))
                    worst["z_bilinear"] = max(worst["z_bilinear"], abs(dlb - ideal) / se)
                    worst["superpixel"] = max(worst["superpixel"], abs(dl - ideal))
                    worst["z_superpixel"] = max(worst["z_superpixel"], abs(dl - ideal) / se)
                    if pol:
                        worst["polarid"] = max(worst["polarid"], abs(pd - ideal))
                        worst["z_polarid"] = max(worst["z_polarid"], abs(pd - ideal) / (se * 1.0))
                print(f"{cap['name']:4s} {p['name']:15s} {wl:4.0f} {rec['region_s0_dn']:7.0f} {ideal:8.5f} {dl:8.5f} "
                      f"{se:7.5f} {dlb:8.5f} {pd:8.5f}{'' if lit else '  (S0 < 100 DN)'}")
    print("per plate and band, over the captures with S0 >= 100 DN: max |DoLP - ideal region DoLP| of the numpy "
          "bilinear and polarid stokes --color region means; max |eq. (9) at the region's centre pixel - ideal| "
          "(the spread of beta over the region)")
    for (name, wl), (b_, p_, e_, n_) in sorted(per_plate.items()):
        print(f"  {name:15s} {wl:4.0f} nm: {n_:2d} captures, bilinear {b_:.5f}, polarid {p_:.5f}, "
              f"eq9 at centre {e_:.4f}")
    for wl, ch in truth["checks_per_band"].items():
        print(f"band {wl}: rendered ideal pixel DoLP vs eq. (9) at the pixel's beta: max "
              f"{ch['max_abs_dolp_minus_eq9_at_pixels']:.1e}; AoLP vs s direction max "
              f"{ch['max_abs_aolp_minus_s_direction_deg']:.3f} deg")
    print(f"regions with S0 >= 100 DN: max |DoLP - ideal| numpy bilinear per lattice {worst['bilinear']:.5f} "
          f"(max {worst['z_bilinear']:.2f} super-pixel SE), super-pixels {worst['superpixel']:.5f} "
          f"(max {worst['z_superpixel']:.2f} SE)" + (f", polarid stokes --color {worst['polarid']:.5f} "
                                                       f"({worst['z_polarid']:.2f} super-pixel SE)" if args.polarid else ""))
    if args.polarid:
        # polarid stokes --color's per-band Stokes images as single-band Stokes captures
        with open(os.path.join(root, "manifest_colour.toml")) as f:
            src = f.read()
        manifests = []
        for wl in sorted(set(bands.values())):
            out = []
            for line in src.splitlines():
                if line.startswith("bands = "):
                    out.append(f"wavelength_nm = {wl:.1f}")
                elif line.startswith("dark_level = "):
                    out.append("dark_level = 0.0")
                elif line.startswith("saturation = "):
                    continue
                elif line.startswith("dofp = "):
                    capname = line.split('"')[1].split("/")[0]
                    fs = {c: os.path.join(tmp, capname, f"{c}_{wl:g}.tif") for c in ("s0", "s1", "s2")}
                    out.append(f'stokes = {{ s0 = "{fs["s0"]}", s1 = "{fs["s1"]}", s2 = "{fs["s2"]}" }}')
                else:
                    out.append(line)
            mp = os.path.join(tmp, f"stokes_{wl:g}.toml")
            with open(mp, "w") as f:
                f.write("\n".join(out) + "\n")
            manifests.append((wl, mp))
        mono_fits(truth, args.polarid, manifests,
                  "polarid stokes --color per capture, then measure + fit of per-band Stokes manifests")
        mono_fits(truth, args.polarid,
                  [(s["wavelength_nm"], os.path.join(root, s["manifest"])) for s in truth["separated"].values()],
                  "polarid measure + fit on the separated half-resolution mono mosaics (bilinear on a "
                  "non-uniform sub-lattice: biased where the brightness has a gradient)")
    shutil.rmtree(tmp, ignore_errors=True)


def mono_fits(truth, polarid, manifests, title):
    """polarid measure + fit (calibrated geometry, --film-sd-nm 0) of single-band
    manifests [(wavelength, path)]: (n, k) against the truth, tolerance max(0.03, 3 SE)
    in n and max(0.06, 3 SE) in k."""
    import csv

    tmp = tempfile.mkdtemp(prefix="colour_mono_")
    print(title + ":")
    for wl, m in sorted(manifests):
        meas = os.path.join(tmp, f"m{wl:g}.csv")
        r = subprocess.run([polarid, "measure", m, "-o", meas, "-q"], capture_output=True, text=True)
        if r.returncode != 0:
            print(f"  {wl:g}: measure failed: {r.stderr.strip()}")
            continue
        for extra, tag in ((["--film-sd-nm", "0"], "film 0"),):
            fits = os.path.join(tmp, f"f{wl:g}{tag}.csv")
            r = subprocess.run([polarid, "fit", meas, "-o", fits, "-q"] + extra, capture_output=True, text=True)
            if r.returncode != 0:
                print(f"  {wl:g}: fit failed: {r.stderr.strip()}")
                continue
            with open(fits) as f:
                rows = {row["target"]: row for row in csv.DictReader(line for line in f if not line.startswith("#"))}
            for p in truth["plates"]:
                t = p["bands"][f"{wl:g}"]
                row = rows.get(p["name"])
                if row is None:
                    print(f"  {wl:4g} {tag:7s} {p['name']:15s} no fit")
                    continue
                n, k, nse, kse = (float(row[q]) for q in ("n", "k", "n_se", "k_se"))
                tn, tk = max(0.03, 3 * nse), max(0.06, 3 * kse)
                ok = abs(n - t["n"]) <= tn and abs(k - t["k"]) <= tk
                print(f"  {wl:4g} {tag:7s} {p['name']:15s} truth {t['n']:.3f}+{t['k']:.3f}i fit {n:.3f}+{k:.3f}i "
                      f"(se {nse:.4f}, {kse:.4f}; {row.get('status')}) dn {n - t['n']:+.4f} (tol {tn:.3f}) "
                      f"dk {k - t['k']:+.4f} (tol {tk:.3f}){'' if t['well_lit'] else ' [not well lit]'}"
                      f"{'' if ok else '  MISS'}")
    shutil.rmtree(tmp, ignore_errors=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("render", help="render every band of a bench TOML and assemble the colour set")
    r.add_argument("scene")
    r.add_argument("-o", "--output", required=True)
    r.add_argument("--color", default="RGGB", help="colour of each 2x2 polarizer block, block-row by block-row")
    r.add_argument("--bands", default="R=650,G=550,B=450", help="colour letter = wavelength (nm)")
    r.add_argument("--variant", default="auto")
    r.add_argument("--force", action="store_true", help="replace an existing colour set")
    r.add_argument("--rerender", action="store_true", help="re-render bands already present")
    r.add_argument("--quiet", action="store_true")
    a = sub.add_parser("assemble", help="assemble the colour set from OUTDIR/bands/band_<nm>")
    a.add_argument("dir")
    a.add_argument("--color", default="RGGB")
    a.add_argument("--bands", default="R=650,G=550,B=450")
    c = sub.add_parser("check", help="re-measure a colour set")
    c.add_argument("dir")
    c.add_argument("--polarid", help="path of the polarid binary (stokes --color, mono path on separated mosaics)")
    args = ap.parse_args()
    {"render": cmd_render, "assemble": cmd_assemble, "check": cmd_check}[args.cmd](args)


if __name__ == "__main__":
    main()
