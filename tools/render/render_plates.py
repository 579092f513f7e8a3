#!/usr/bin/env python3
"""Independent polarized renders of flat material plates with Mitsuba 3.

Renders uniform plates (rough Fresnel reflectors with complex index n + ik, optionally
blended with a depolarizing Lambertian component) lit by a distant unpolarized source in
the plane of incidence, and writes polarid capture sets: rotating-polarizer frames
(0/45/90/135 deg), a division-of-focal-plane raw mosaic, ideal float32 Stokes images,
manifests (docs/FORMATS.md) and the ground truth.

Subcommands (see tools/render/README.md):

    render_plates.py render SCENE.toml -o OUTDIR [--variant V] [--force]
    render_plates.py check OUTDIR        # re-measure the written files against truth.json
    render_plates.py verify [--variant V] # Stokes-convention and eq. (9) checks
    render_plates.py smoke                # quick Brewster-angle check (used by setup.sh)

The project's conventions (docs/CONVENTIONS.md): S1 = I(0) - I(90), S2 = I(45) - I(135),
polarizer angle counter-clockwise from the displayed image's +x axis. Mitsuba's `stokes`
integrator output was verified to be in exactly that frame for the sensors built here
(see `verify`), so the mapping Mitsuba -> project is the identity: S0=S0, S1=S1, S2=S2.
"""

from __future__ import annotations

import argparse
import glob
import json
import math
import os
import shutil
import sys
import time
import tomllib
from dataclasses import dataclass, field

import numpy as np

# ----------------------------------------------------------------------------------------
# Mitsuba set-up
# ----------------------------------------------------------------------------------------

_LLVM_CANDIDATES = [
    "/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1",
    "/usr/lib/x86_64-linux-gnu/libLLVM-19.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM-18.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM-17.so",
    "/usr/lib/x86_64-linux-gnu/libLLVM-16.so",
    "/usr/lib/aarch64-linux-gnu/libLLVM.so.19.1",
]

DEFAULT_LLVM_VARIANT = "llvm_ad_mono_polarized"
DEFAULT_SCALAR_VARIANT = "scalar_spectral_polarized"

mi = None  # the mitsuba module, once a variant is set


def _find_llvm() -> str | None:
    """Path of a libLLVM >= 16 (Dr.Jit 1.5 fails with Debian bookworm's LLVM 14/15)."""
    env = os.environ.get("DRJIT_LIBLLVM_PATH")
    if env and os.path.exists(env):
        return env
    for p in _LLVM_CANDIDATES:
        if os.path.exists(p):
            return p
    return None


def init_mitsuba(variant: str = "auto") -> str:
    """Import mitsuba and set a polarized variant; returns the variant used.

    `auto` picks llvm_ad_mono_polarized when a libLLVM >= 16 is present (it is pointed to
    with DRJIT_LIBLLVM_PATH before Dr.Jit loads), else scalar_spectral_polarized.
    """
    global mi
    llvm = _find_llvm()
    if llvm:
        os.environ["DRJIT_LIBLLVM_PATH"] = llvm
    if variant == "auto":
        variant = DEFAULT_LLVM_VARIANT if llvm else DEFAULT_SCALAR_VARIANT
    if "polarized" not in variant:
        raise SystemExit(f"variant {variant!r} is not a polarized variant")
    if variant.startswith("llvm") and not llvm:
        raise SystemExit(
            f"variant {variant!r} needs libLLVM >= 16 (apt-get install libllvm19) "
            "or DRJIT_LIBLLVM_PATH; use --variant scalar_spectral_polarized"
        )
    import mitsuba as _mi

    if variant not in _mi.variants():
        raise SystemExit(f"variant {variant!r} not in this wheel: {_mi.variants()}")
    _mi.set_variant(variant)
    _mi.set_log_level(_mi.LogLevel.Error)
    mi = _mi
    return variant


# ----------------------------------------------------------------------------------------
# Physics helpers (closed forms the renders are checked against)
# ----------------------------------------------------------------------------------------


def dop_eq9(n: float, k: float, beta: float) -> float:
    """Paper eq. (9): DoLP of unpolarized light specularly reflected at angle beta (rad)."""
    s, c = math.sin(beta), math.cos(beta)
    d = n * n - k * k - s * s
    cc = 4 * n * n * k * k + d * d
    a = math.sqrt((math.sqrt(cc) + d) / 2)
    b = math.sqrt(max((math.sqrt(cc) - d) / 2, 0.0))
    return 2 * a * s * s * c / (a * a * c * c + s**4 + b * b * c * c)


def fresnel_rs_rp(n: float, k: float, beta: float):
    """Fresnel power reflectances (Rs, Rp) of air -> n + ik at incidence angle beta (rad)."""
    import cmath

    N = complex(n, k)
    c, s = math.cos(beta), math.sin(beta)
    ct = cmath.sqrt(N * N - s * s)
    rs = (c - ct) / (c + ct)
    rp = (N * N * c - ct) / (N * N * c + ct)
    return abs(rs) ** 2, abs(rp) ** 2


def priest_meier_f00(n, k, sigma, theta_i, theta_r, beta, tilt):
    """Eq. (3) with m00 = (Rs + Rp) / 2: the unpolarized pBRDF element f00 in sr^-1."""
    rs, rp = fresnel_rs_rp(n, k, beta)
    return ((rs + rp) / 2 / (8 * math.pi * sigma**2 * math.cos(tilt) ** 4)
            * math.exp(-math.tan(tilt) ** 2 / (2 * sigma**2)) / (math.cos(theta_r) * math.cos(theta_i)))


def beta_of(theta_i: float, theta_r: float, phi: float = math.pi) -> float:
    """Eq. (5): half the source-camera angle (radians in, radians out)."""
    c2b = math.cos(theta_i) * math.cos(theta_r) + math.sin(theta_i) * math.sin(theta_r) * math.cos(phi)
    return 0.5 * math.acos(max(-1.0, min(1.0, c2b)))


def facet_tilt(theta_i: float, theta_r: float, beta: float) -> float:
    """Eq. (4): microfacet tilt from the mean normal (radians)."""
    return math.acos(max(-1.0, min(1.0, (math.cos(theta_i) + math.cos(theta_r)) / (2 * math.cos(beta)))))


# ----------------------------------------------------------------------------------------
# Scene description
# ----------------------------------------------------------------------------------------


@dataclass
class Plate:
    name: str
    cls: str
    n: float
    k: float
    sigma: float
    diffuse_fraction: float = 0.0  # diffuse / (diffuse + specular) at the specular peak
    diffuse_albedo: float = 0.8
    diffuse_weight: float = 0.0  # blendbsdf weight, derived from diffuse_fraction
    # rendered radiance of the diffuse BSDF alone (weight 1) at theta_i = theta_r
    diffuse_peak_radiance: float = 0.0
    # pixel rectangles [x, y, w, h] (x = column, y = row)
    plate_rect: list = field(default_factory=list)
    region: list = field(default_factory=list)

    @property
    def alpha(self) -> float:
        """Beckmann alpha = sqrt(2) sigma (paper eq. (3): exp(-tan^2/(2 sigma^2)))."""
        return math.sqrt(2.0) * self.sigma


@dataclass
class Scene:
    name: str
    theta_r_deg: float
    theta_i_deg: list
    plates: list
    width: int = 256
    height: int = 256
    columns: int = 2
    gap_px: int = 12
    region_px: int = 64
    spp: int = 16
    wavelength_nm: float = 650.0
    seed: int = 1
    file_format: str = "tif"
    exposure: str | float = "auto"
    full_scale_fraction: float = 0.7
    electrons_per_dn: float = 8.0
    read_noise_dn: float = 2.0
    dark_level: float = 64.0
    bits: int = 12
    dofp_pattern: list = field(default_factory=lambda: [90, 45, 135, 0])

    @property
    def saturation(self) -> float:
        return float(2**self.bits - 1)


def _fail(path: str, msg: str):
    raise SystemExit(f"{path}: {msg}")


def load_scene(path: str) -> Scene:
    """Read a scene TOML (format in README.md), validate it and lay the plates out."""
    with open(path, "rb") as f:
        try:
            d = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            _fail(path, f"invalid TOML: {e}")
    known = set(Scene.__dataclass_fields__) | {"plate", "sensor", "image", "layout"}
    for key in d:
        if key not in known:
            _fail(path, f"unknown key {key!r}")
    for req in ("name", "theta_r_deg", "theta_i_deg", "plate"):
        if req not in d:
            _fail(path, f"missing key {req!r}")
    plates = []
    for i, p in enumerate(d["plate"]):
        for req in ("name", "n", "k", "sigma"):
            if req not in p:
                _fail(path, f"[[plate]] #{i + 1}: missing key {req!r}")
        pl = Plate(
            name=str(p["name"]),
            cls=str(p.get("class", p["name"])),
            n=float(p["n"]),
            k=float(p["k"]),
            sigma=float(p["sigma"]),
            diffuse_fraction=float(p.get("diffuse_fraction", 0.0)),
            diffuse_albedo=float(p.get("diffuse_albedo", 0.8)),
        )
        if not (pl.n > 0 and pl.k >= 0 and 0 < pl.sigma < 1.5):
            _fail(path, f"plate {pl.name!r}: need n > 0, k >= 0, 0 < sigma < 1.5")
        if not (0 <= pl.diffuse_fraction < 1 and 0 < pl.diffuse_albedo <= 1):
            _fail(path, f"plate {pl.name!r}: need 0 <= diffuse_fraction < 1, 0 < diffuse_albedo <= 1")
        plates.append(pl)
    if len({p.name for p in plates}) != len(plates):
        _fail(path, "plate names must be unique")
    ti = d["theta_i_deg"]
    if isinstance(ti, dict):  # {start, stop, step}
        ti = list(np.arange(ti["start"], ti["stop"] + 1e-9, ti["step"]))
    sc = Scene(
        name=str(d["name"]),
        theta_r_deg=float(d["theta_r_deg"]),
        theta_i_deg=[float(t) for t in ti],
        plates=plates,
    )
    for key in ("spp", "wavelength_nm", "seed", "file_format", "exposure", "gap_px", "region_px", "columns"):
        if key in d:
            setattr(sc, key, d[key])
    img = d.get("image", {})
    sc.width = int(img.get("width", sc.width))
    sc.height = int(img.get("height", sc.height))
    sen = d.get("sensor", {})
    for key in ("electrons_per_dn", "read_noise_dn", "dark_level", "bits", "full_scale_fraction", "exposure", "dofp_pattern"):
        if key in sen:
            setattr(sc, key, sen[key])
    if sc.file_format not in ("tif", "png"):
        _fail(path, f"file_format must be 'tif' or 'png', got {sc.file_format!r}")
    if not (sc.exposure in ("auto", "fixed") or isinstance(sc.exposure, (int, float))):
        _fail(path, f"exposure must be 'auto', 'fixed' or a gain in DN per unit radiance, got {sc.exposure!r}")
    if sorted(sc.dofp_pattern) != [0, 45, 90, 135]:
        _fail(path, f"dofp_pattern must be a permutation of 0,45,90,135, got {sc.dofp_pattern}")
    if not all(0 <= t < 90 for t in sc.theta_i_deg) or not 0 <= sc.theta_r_deg < 90:
        _fail(path, "zenith angles must be in [0, 90)")
    layout(sc, path)
    return sc


def layout(sc: Scene, path: str = "scene"):
    """Place the plates on a grid; plate and region rects in displayed pixel coordinates."""
    cols = int(sc.columns)
    rows = math.ceil(len(sc.plates) / cols)
    cw, ch = sc.width // cols, sc.height // rows
    size = min(cw, ch) - 2 * int(sc.gap_px)
    r = int(sc.region_px)
    if r % 2 or r < 40 or r > size - 8:
        _fail(path, f"region_px={r} must be even, >= 40 and fit in a plate of {size} px with a 4 px margin")
    for i, p in enumerate(sc.plates):
        cx = (i % cols) * cw + cw // 2
        cy = (i // cols) * ch + ch // 2
        p.plate_rect = [cx - size // 2, cy - size // 2, size, size]
        x0 = (cx - r // 2) // 2 * 2  # even: whole DoFP super-pixels
        y0 = (cy - r // 2) // 2 * 2
        p.region = [x0, y0, r, r]


# ----------------------------------------------------------------------------------------
# Rendering
# ----------------------------------------------------------------------------------------


def _bsdf(p: Plate, weight: float | None = None, part: str = "blend") -> dict:
    cond = {"type": "roughconductor", "distribution": "beckmann", "alpha": p.alpha, "eta": p.n, "k": p.k}
    diff = {"type": "diffuse", "reflectance": {"type": "spectrum", "value": p.diffuse_albedo}}
    if part == "specular":
        return cond
    if part == "diffuse":
        return diff
    w = p.diffuse_weight if weight is None else weight
    if w <= 0:
        return cond
    # blendbsdf: (1 - weight) * bsdf_0 + weight * bsdf_1
    return {"type": "blendbsdf", "weight": w, "bsdf_0": cond, "bsdf_1": diff}


def render_stokes(
    shapes: list,
    width: int,
    height: int,
    theta_i_deg: float,
    theta_r_deg: float,
    spp: int = 16,
    roll_deg: float = 0.0,
):
    """Render S0, S1, S2 (float64 H x W arrays, project convention) of plates in z = 0.

    `shapes` is a list of (bsdf_dict, [x, y, w, h]) with rects in displayed pixels.
    Geometry: mean normal +z; the source at zenith theta_i, azimuth 180 deg (on -x); the
    orthographic camera at zenith theta_r, azimuth 0 (on +x), so phi = phi_r - phi_i =
    180 deg. The camera's up vector is +z, so the plane of incidence is the image's
    vertical and world +y is the image's +x (columns increasing). One world unit along y
    is one pixel; along x, one world unit is cos(theta_r) pixels (foreshortening).
    """
    T = mi.ScalarTransform4f
    ti, tr = math.radians(theta_i_deg), math.radians(theta_r_deg)
    dist = 10.0 * (width + height)
    cam = [dist * math.sin(tr), 0.0, dist * math.cos(tr)]
    to_world = T().look_at(origin=cam, target=[0, 0, 0], up=[0, 0, 1])
    if roll_deg:
        to_world = to_world @ T().rotate([0, 0, 1], roll_deg)
    to_world = to_world @ T().scale([width / 2, width / 2, 1])
    scene = {
        "type": "scene",
        "integrator": {"type": "stokes", "integrator": {"type": "direct"}},
        "sensor": {
            "type": "orthographic",
            "near_clip": 1.0,
            "far_clip": 4 * dist,
            "to_world": to_world,
            "film": {"type": "hdrfilm", "width": width, "height": height, "rfilter": {"type": "box"}},
            "sampler": {"type": "stratified", "sample_count": spp},
        },
        # `direction` is the direction of propagation: from the source (zenith theta_i,
        # azimuth 180 deg) towards the surface. Irradiance 1 on a surface facing it.
        "light": {
            "type": "directional",
            "direction": [math.sin(ti), 0.0, -math.cos(ti)],
            "irradiance": {"type": "spectrum", "value": 1.0},
        },
    }
    cos_r = math.cos(tr)
    for j, (bsdf, (x, y, w, h)) in enumerate(shapes):
        # displayed pixel (col, row) <-> world (x_w, y_w): y_w = col - W/2, x_w = (row - H/2)/cos(tr)
        cy_w = x + w / 2 - width / 2
        cx_w = (y + h / 2 - height / 2) / cos_r
        scene[f"plate{j}"] = {
            "type": "rectangle",
            "to_world": T().translate([cx_w, cy_w, 0]) @ T().scale([h / 2 / cos_r, w / 2, 1]),
            "bsdf": bsdf,
        }
    sc = mi.load_dict(scene)
    mi.render(sc, seed=0)
    chans = {name: np.array(b, dtype=np.float64) for name, b in sc.sensors()[0].film().bitmap().split()}
    # Mono variants replicate the value in three channels; spectral variants give RGB of
    # a constant (wavelength-independent) material and source: the ratios S1/S0, S2/S0
    # are the same in every channel, so the channel mean is used.
    s0, s1, s2 = (chans[c].mean(axis=2) if chans[c].ndim == 3 else chans[c] for c in ("S0", "S1", "S2"))
    return mitsuba_to_project(s0, s1, s2)


def mitsuba_to_project(s0, s1, s2):
    """Map Mitsuba's Stokes output to the project's convention.

    Verified (`verify`): for these sensors Mitsuba's stokes integrator expresses the
    Stokes vector in the displayed image frame with S1 > 0 for light polarized along the
    image +x axis and S2 > 0 for light polarized at +45 deg counter-clockwise as
    displayed, which is the project's convention: the mapping is the identity.
    """
    return s0, s1, s2


def diffuse_radiance(p: Plate, theta_i: float, theta_r: float) -> float:
    """Radiance of the Lambertian part, w * Ld_peak * cos(theta_i) / cos(theta_r) (radians).

    Ld_peak is rendered (calibrate_diffuse), so the units are those of the renders in any
    variant (spectral variants scale a unit spectrum by their RGB normalisation, ~2%);
    in mono variants it equals rho cos(theta_i) / pi for irradiance 1.
    """
    return p.diffuse_weight * p.diffuse_peak_radiance * math.cos(theta_i) / math.cos(theta_r)


def calibrate_diffuse(p: Plate, theta_r_deg: float, spp: int = 4) -> dict:
    """Blend weight giving diffuse / (diffuse + specular) = p.diffuse_fraction at the peak.

    The peak is the mirror geometry theta_i = theta_r (facet tilt 0). Radiances of the
    pure specular and pure diffuse components there are rendered, then
    w = f Ls / (f Ls + (1 - f) Ld) solves w Ld / ((1 - w) Ls + w Ld) = f.
    """
    rect = [0, 0, 16, 16]
    ls, _, _ = render_stokes([(_bsdf(p, part="specular"), rect)], 16, 16, theta_r_deg, theta_r_deg, spp)
    ld, _, _ = render_stokes([(_bsdf(p, part="diffuse"), rect)], 16, 16, theta_r_deg, theta_r_deg, spp)
    ls, ld = float(ls[4:12, 4:12].mean()), float(ld[4:12, 4:12].mean())
    f = p.diffuse_fraction
    w = f * ls / (f * ls + (1 - f) * ld) if f > 0 else 0.0
    return {"specular_peak_radiance": ls, "diffuse_peak_radiance_unit_weight": ld, "weight": w}


# ----------------------------------------------------------------------------------------
# Sensor model and files
# ----------------------------------------------------------------------------------------

ANGLES = (0, 45, 90, 135)


def polarizer(s0, s1, s2, a_deg):
    """I(a) = (S0 + S1 cos 2a + S2 sin 2a) / 2 (docs/CONVENTIONS.md)."""
    a = math.radians(a_deg)
    return 0.5 * (s0 + s1 * math.cos(2 * a) + s2 * math.sin(2 * a))


def dofp_angles(pattern, h, w):
    """Per-pixel polarizer angle of a DoFP mosaic; pattern row by row, top-left first."""
    ang = np.empty((h, w))
    ang[0::2, 0::2] = pattern[0]
    ang[0::2, 1::2] = pattern[1]
    ang[1::2, 0::2] = pattern[2]
    ang[1::2, 1::2] = pattern[3]
    return ang


def expose(ideal, gain, sc: Scene, rng):
    """Ideal radiance -> 12-bit counts: shot noise (Poisson in electrons), Gaussian read
    noise, dark level, rounding, clipping to [0, 2^bits - 1] (saturation)."""
    electrons = rng.poisson(np.clip(ideal, 0, None) * gain * sc.electrons_per_dn)
    dn = electrons / sc.electrons_per_dn + rng.normal(0.0, sc.read_noise_dn, ideal.shape) + sc.dark_level
    return np.clip(np.rint(dn), 0, sc.saturation).astype(np.uint16)


def write_image(path, arr):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    if path.endswith(".png"):
        from PIL import Image

        Image.fromarray(arr.astype(np.uint16)).save(path)  # 16-bit grayscale PNG (mode I;16)
    else:
        import tifffile

        tifffile.imwrite(path, arr)


def read_image(path):
    if path.endswith(".png"):
        from PIL import Image

        return np.array(Image.open(path)).astype(np.float64)
    import tifffile

    return tifffile.imread(path).astype(np.float64)


def _fmt_deg(t: float) -> str:
    return f"{t:g}"


def region_mean(img, rect):
    x, y, w, h = rect
    return float(img[y : y + h, x : x + w].mean())


def dolp_aolp(s0, s1, s2):
    return math.hypot(s1, s2) / s0, (math.degrees(math.atan2(s2, s1)) / 2) % 180.0


def write_manifest(path, sc: Scene, captures, kind: str):
    lines = [
        f"# polarid capture set rendered by tools/render/render_plates.py (Mitsuba 3), scene {sc.name!r}",
        f"# {kind} captures; ground truth in truth.json",
        f"theta_r_deg = {sc.theta_r_deg:.1f}",
        "phi_deg = 180.0",
        f"dark_level = {float(sc.dark_level) if kind != 'stokes' else 0.0:.1f}",
    ]
    if kind != "stokes":
        lines.append(f"saturation = {sc.saturation:.1f}")
    lines.append(f"wavelength_nm = {float(sc.wavelength_nm):.1f}")
    for p in sc.plates:
        lines += ["", "[[region]]", f'name = "{p.name}"', f"rect = {p.region}", f'class = "{p.cls}"']
    for c in captures:
        d = c["dir"]
        lines += ["", "[[capture]]", f"theta_i_deg = {c['theta_i_deg']:.1f}"]
        if kind == "frames":
            lines.append(f"exposure = {c['exposure']:.9g}")
            lines.append("frames = [")
            for a in ANGLES:
                lines.append(f'  {{ angle_deg = {a:.1f}, file = "{d}/pol{a:03d}.{sc.file_format}" }},')
            lines.append("]")
        elif kind == "dofp":
            lines.append(f"exposure = {c['exposure']:.9g}")
            pat = ", ".join(str(int(a)) for a in sc.dofp_pattern)
            lines.append(f'dofp = {{ file = "{d}/raw.{sc.file_format}", pattern = [{pat}] }}')
        else:
            lines.append(f'stokes = {{ s0 = "ideal/{d}/s0.tif", s1 = "ideal/{d}/s1.tif", s2 = "ideal/{d}/s2.tif" }}')
    with open(path, "w") as f:
        f.write("\n".join(lines) + "\n")


def cmd_render(args):
    sc = load_scene(args.scene)
    variant = init_mitsuba(args.variant)
    out = os.path.abspath(args.output)
    if os.path.exists(out) and not args.force:
        raise SystemExit(f"{out} exists (use --force to replace it)")
    tmp = out + ".partial"
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)
    t0 = time.time()
    calib = {}
    for p in sc.plates:
        if p.diffuse_fraction > 0:
            calib[p.name] = calibrate_diffuse(p, sc.theta_r_deg)
            p.diffuse_weight = calib[p.name]["weight"]
            p.diffuse_peak_radiance = calib[p.name]["diffuse_peak_radiance_unit_weight"]
    shapes = [(_bsdf(p), p.plate_rect) for p in sc.plates]
    tr = math.radians(sc.theta_r_deg)
    renders = []
    for ti_deg in sc.theta_i_deg:
        t = time.time()
        s0, s1, s2 = render_stokes(shapes, sc.width, sc.height, ti_deg, sc.theta_r_deg, sc.spp)
        renders.append((ti_deg, s0, s1, s2))
        if not args.quiet:
            print(f"  theta_i {ti_deg:5.1f}: rendered in {time.time() - t:.2f} s", file=sys.stderr)
    t_render = time.time() - t0

    # Exposure: per-capture auto gain puts the brightest plate pixel of any polarizer
    # frame at full_scale_fraction of full scale; 'fixed' uses one gain for the set;
    # a number is the gain itself (DN per unit radiance). The manifest's `exposure` is
    # the gain relative to the set's smallest gain, so S0 / exposure is comparable.
    full = sc.saturation - float(sc.dark_level)
    plate_mask = np.zeros((sc.height, sc.width), bool)
    for p in sc.plates:
        x, y, w, h = p.plate_rect
        plate_mask[y : y + h, x : x + w] = True
    peaks = []
    for _, s0, s1, s2 in renders:
        peaks.append(max(float(polarizer(s0, s1, s2, a)[plate_mask].max()) for a in ANGLES))
    for ti_deg, pk in zip(sc.theta_i_deg, peaks):
        if not pk > 0:
            shutil.rmtree(tmp, ignore_errors=True)
            raise SystemExit(f"{args.scene}: every plate is black at theta_i_deg = {ti_deg:g} "
                             "(no reflected light reaches the camera); check n, k, sigma and the angles")
    if sc.exposure == "auto":
        gains = [sc.full_scale_fraction * full / pk for pk in peaks]
    elif sc.exposure == "fixed":
        gains = [sc.full_scale_fraction * full / max(peaks)] * len(peaks)
    else:
        gains = [float(sc.exposure)] * len(peaks)
    g_ref = min(gains)

    rng = np.random.default_rng(sc.seed)
    captures = []
    truth_rows = []
    pat_ang = dofp_angles(sc.dofp_pattern, sc.height, sc.width)
    for (ti_deg, s0, s1, s2), gain, peak in zip(renders, gains, peaks):
        ti = math.radians(ti_deg)
        beta = beta_of(ti, tr)
        d = "i" + _fmt_deg(ti_deg)
        exposure = gain / g_ref
        frames = {a: polarizer(s0, s1, s2, a) for a in ANGLES}
        for a in ANGLES:
            write_image(os.path.join(tmp, d, f"pol{a:03d}.{sc.file_format}"), expose(frames[a], gain, sc, rng))
        mosaic = np.zeros_like(s0)
        for a in ANGLES:
            mosaic[pat_ang == a] = frames[a][pat_ang == a]
        write_image(os.path.join(tmp, d, f"raw.{sc.file_format}"), expose(mosaic, gain, sc, rng))
        import tifffile

        os.makedirs(os.path.join(tmp, "ideal", d), exist_ok=True)
        for nm, img in (("s0", s0), ("s1", s1), ("s2", s2)):
            # ideal Stokes in the units of S0 / exposure of the frames (DN at gain g_ref)
            tifffile.imwrite(os.path.join(tmp, "ideal", d, f"{nm}.tif"), (img * g_ref).astype(np.float32))
        cap = {
            "theta_i_deg": ti_deg,
            "theta_r_deg": sc.theta_r_deg,
            "phi_deg": 180.0,
            "beta_deg": math.degrees(beta),
            "facet_tilt_deg": math.degrees(facet_tilt(ti, tr, beta)),
            "dir": d,
            "gain_dn_per_radiance": gain,
            "exposure": exposure,
            "brightest_plate_dn": peak * gain,
            "plates": {},
        }
        for p in sc.plates:
            m = [region_mean(img, p.region) for img in (s0, s1, s2)]
            x, y, w, h = p.region
            cv = float(s0[y : y + h, x : x + w].std() / max(m[0], 1e-30))
            dolp, aolp = dolp_aolp(*m) if m[0] > 0 else (float("nan"), float("nan"))
            p9 = dop_eq9(p.n, p.k, beta)
            ld = diffuse_radiance(p, ti, tr)
            tilt = facet_tilt(ti, tr, beta)
            f00 = priest_meier_f00(p.n, p.k, p.sigma, ti, tr, beta, tilt)
            # rendered specular radiance / ((1 - w) f00 cos(theta_i)): Mitsuba's Smith
            # shadowing-masking G, which eq. (3) omits (exact in mono variants)
            shadowing = (m[0] - ld) / ((1 - p.diffuse_weight) * f00 * math.cos(ti))
            expected = p9 * (m[0] - ld) / m[0] if m[0] > 0 else float("nan")
            cap["plates"][p.name] = {
                "dolp": dolp,
                "aolp_deg": aolp,
                "s0_radiance": m[0],
                "s0_dn_per_exposure": m[0] * g_ref,
                "s0_region_cv": cv,
                "dolp_eq9_specular": p9,
                "dolp_expected_with_diffuse": expected,
                "diffuse_share_of_s0": ld / m[0] if m[0] > 0 else float("nan"),
                "priest_meier_f00_per_sr": f00,
                "smith_shadowing_factor": shadowing,
            }
            truth_rows.append(
                (p.name, p.cls, ti_deg, sc.theta_r_deg, 180.0, math.degrees(beta), dolp, m[0] * g_ref, p9)
            )
        captures.append(cap)

    import mitsuba as _m

    truth = {
        "scene": sc.name,
        "source_scene_file": os.path.abspath(args.scene),
        "renderer": {
            "mitsuba": _m.__version__,
            "variant": variant,
            "spp": sc.spp,
            "integrator": "stokes(direct)",
            "sensor": "orthographic",
            "emitter": "directional, unpolarized, irradiance 1",
            "render_seconds": round(t_render, 2),
        },
        "stokes_convention": "S1 = I(0) - I(90), S2 = I(45) - I(135); polarizer angle counter-clockwise "
        "from displayed image +x; Mitsuba stokes output mapped with the identity (verified)",
        "image": {"width": sc.width, "height": sc.height},
        "wavelength_nm": sc.wavelength_nm,
        "sensor": {
            "bits": sc.bits,
            "saturation_dn": sc.saturation,
            "dark_level_dn": sc.dark_level,
            "electrons_per_dn": sc.electrons_per_dn,
            "read_noise_dn": sc.read_noise_dn,
            "exposure_mode": sc.exposure,
            "full_scale_fraction": sc.full_scale_fraction,
            "reference_gain_dn_per_radiance": g_ref,
            "dofp_pattern": sc.dofp_pattern,
            "seed": sc.seed,
        },
        "plates": [
            {
                "name": p.name,
                "class": p.cls,
                "n": p.n,
                "k": p.k,
                "sigma": p.sigma,
                "beckmann_alpha": p.alpha,
                "diffuse_fraction_at_peak": p.diffuse_fraction,
                "diffuse_albedo": p.diffuse_albedo,
                "diffuse_blend_weight": p.diffuse_weight,
                # Lambertian albedo relative to the specular term's scale: (1-w) f_spec + w rho/pi
                # = (1-w) (f_spec + rho_d/pi) with rho_d = w rho / (1 - w).
                "rho_d_equivalent": p.diffuse_weight * p.diffuse_albedo / (1 - p.diffuse_weight),
                "diffuse_calibration": calib.get(p.name),
                "plate_rect": p.plate_rect,
                "region": p.region,
            }
            for p in sc.plates
        ],
        "captures": captures,
    }
    with open(os.path.join(tmp, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    with open(os.path.join(tmp, "truth.csv"), "w") as f:
        f.write("# ideal (noise-free) region values; s0 in DN / exposure (the manifests' units)\n")
        f.write("target,class,theta_i_deg,theta_r_deg,phi_deg,beta_deg,dolp,s0,dolp_eq9_specular\n")
        for r in truth_rows:
            f.write(",".join([r[0], r[1]] + [f"{v:.10g}" for v in r[2:]]) + "\n")
    write_manifest(os.path.join(tmp, "manifest.toml"), sc, captures, "frames")
    write_manifest(os.path.join(tmp, "manifest_dofp.toml"), sc, captures, "dofp")
    write_manifest(os.path.join(tmp, "manifest_stokes.toml"), sc, captures, "stokes")
    shutil.copy(args.scene, os.path.join(tmp, "scene.toml"))
    if os.path.exists(out):
        shutil.rmtree(out)
    os.rename(tmp, out)
    print(f"{sc.name}: {len(renders)} captures, {sc.width}x{sc.height}, variant {variant}, "
          f"render {t_render:.1f} s, total {time.time() - t0:.1f} s -> {out}")


# ----------------------------------------------------------------------------------------
# check: re-measure the written files (an independent, simple reference measurement)
# ----------------------------------------------------------------------------------------


def cmd_check(args):
    root = os.path.abspath(args.dir)
    with open(os.path.join(root, "truth.json")) as f:
        truth = json.load(f)
    with open(os.path.join(root, "manifest.toml"), "rb") as f:
        man = tomllib.load(f)
    with open(os.path.join(root, "manifest_dofp.toml"), "rb") as f:
        man_d = tomllib.load(f)
    dark = float(man.get("dark_level", 0.0))
    sat = float(man.get("saturation", 65535))
    worst = {"frames": 0.0, "dofp": 0.0}
    n_rej = 0
    print(f"{'target':14s} {'th_i':>5s} {'ideal':>8s} {'eq9':>8s} {'frames':>8s} {'se':>7s} {'dofp':>8s} {'se':>7s}")
    for cap, capd, tc in zip(man["capture"], man_d["capture"], truth["captures"]):
        fr = {int(f_["angle_deg"]): read_image(os.path.join(root, f_["file"])) for f_ in cap["frames"]}
        raw = read_image(os.path.join(root, capd["dofp"]["file"]))
        pat = capd["dofp"]["pattern"]
        for reg in man["region"]:
            x, y, w, h = reg["rect"]
            sl = (slice(y, y + h), slice(x, x + w))
            I = {a: fr[a][sl] for a in ANGLES}
            n_rej += int(sum(((I[a] >= sat) | (I[a] <= 0)).sum() for a in ANGLES))
            n_rej += int(((raw[sl] >= sat) | (raw[sl] <= 0)).sum())
            I = {a: v - dark for a, v in I.items()}
            s0 = 0.5 * (I[0] + I[45] + I[90] + I[135])
            s1 = I[0] - I[90]
            s2 = I[45] - I[135]
            dl_f, se_f = _dolp_se(s0, s1, s2)
            # DoFP, super-pixel demosaicing (half resolution)
            r = raw[sl] - dark
            q = {pat[0]: r[0::2, 0::2], pat[1]: r[0::2, 1::2], pat[2]: r[1::2, 0::2], pat[3]: r[1::2, 1::2]}
            d0 = 0.5 * (q[0] + q[45] + q[90] + q[135])
            dl_d, se_d = _dolp_se(d0, q[0] - q[90], q[45] - q[135])
            t = tc["plates"][reg["name"]]
            worst["frames"] = max(worst["frames"], abs(dl_f - t["dolp"]))
            worst["dofp"] = max(worst["dofp"], abs(dl_d - t["dolp"]))
            print(f"{reg['name']:14s} {tc['theta_i_deg']:5.1f} {t['dolp']:8.5f} {t['dolp_eq9_specular']:8.5f} "
                  f"{dl_f:8.5f} {se_f:7.5f} {dl_d:8.5f} {se_d:7.5f}")
    print(f"max |DoLP - ideal|: frames {worst['frames']:.5f}, dofp {worst['dofp']:.5f}; "
          f"clipped (0 or saturated) raw pixels in regions: {n_rej}")


def _dolp_se(s0, s1, s2):
    """DoLP of the mean Stokes vector and its standard error (delta method)."""
    m0, m1, m2 = s0.mean(), s1.mean(), s2.mean()
    p = math.hypot(m1, m2) / m0
    # dP/dS = (-P/S0, S1/(S0 |S12|), S2/(S0 |S12|))
    l = max(math.hypot(m1, m2), 1e-30)
    g = np.array([-p / m0, m1 / (m0 * l), m2 / (m0 * l)])
    X = np.stack([s0.ravel(), s1.ravel(), s2.ravel()])
    cov = np.cov(X) / X.shape[1]
    return p, float(math.sqrt(max(g @ cov @ g, 0.0)))


# ----------------------------------------------------------------------------------------
# verify: conventions and agreement with eq. (9)
# ----------------------------------------------------------------------------------------


def _plate(n, k, sigma, f=0.0):
    return Plate(name="p", cls="p", n=n, k=k, sigma=sigma, diffuse_fraction=f)


def check_brewster(verbose=True) -> bool:
    """k = 0 dielectric at Brewster (beta = atan n): DoLP ~ 1, s-polarized, i.e. polarized
    perpendicular to the plane of incidence = along world y = image +x: AoLP = 0 deg,
    S1 > 0 (I(0) > I(90))."""
    n = 1.5
    tb = math.degrees(math.atan(n))
    s0, s1, s2 = render_stokes([(_bsdf(_plate(n, 0.0, 0.2)), [8, 8, 48, 48])], 64, 64, tb, tb, 4)
    m = [region_mean(a, [16, 16, 32, 32]) for a in (s0, s1, s2)]
    dolp, aolp = dolp_aolp(*m)
    aolp = (aolp + 90) % 180 - 90  # signed, near 0
    ok = dolp > 0.999 and m[1] > 0 and abs(aolp) < 0.1
    if verbose:
        print(f"Brewster n=1.5, theta_i=theta_r={tb:.2f}: S1/S0={m[1] / m[0]:+.6f} S2/S0={m[2] / m[0]:+.2e} "
              f"DoLP={dolp:.6f} AoLP={aolp:.3f} deg (expect DoLP 1, AoLP 0: s-pol along image +x) "
              f"{'OK' if ok else 'FAIL'}")
    return ok


def check_roll(roll_deg: float) -> bool:
    """Roll the camera about its axis: the s-polarization direction (world +y) is found in
    the displayed image from a marker plate placed at +y, independently of Mitsuba's
    Stokes frame; the rendered AoLP must equal that displayed angle."""
    n = 1.5
    tb = math.degrees(math.atan(n))
    W = 96
    # marker plate centred on world (0, +30, 0); rect in unrolled pixels
    s0, s1, s2 = render_stokes([(_bsdf(_plate(n, 0.0, 0.2)), [W // 2 + 30 - 6, W // 2 - 6, 12, 12])],
                               W, W, tb, tb, 16, roll_deg=roll_deg)
    mask = s0 > 1e-3 * s0.max()
    rows, cols = np.nonzero(mask)
    dx = cols.mean() + 0.5 - W / 2
    dy = -(rows.mean() + 0.5 - W / 2)  # displayed: up is rows decreasing
    expect = math.degrees(math.atan2(dy, dx)) % 180
    dolp, aolp = dolp_aolp(s0[mask].mean(), s1[mask].mean(), s2[mask].mean())
    diff = (aolp - expect + 90) % 180 - 90
    ok = abs(diff) < 1.0 and dolp > 0.99
    print(f"camera roll {roll_deg:+5.1f} deg: world +y displayed at {expect:7.2f} deg, rendered AoLP "
          f"{aolp:7.2f} deg (diff {diff:+.2f}) DoLP={dolp:.5f} {'OK' if ok else 'FAIL'}")
    return ok


def check_eq9(theta_r=60.0, thetas=(35, 50, 65, 80)) -> float:
    mats = [("green_paint", 1.39, 0.34), ("aluminum", 1.24, 6.60), ("copper", 0.4, 2.95), ("glass", 1.5, 0.0)]
    worst = 0.0
    print(f"eq. (9) vs rendered DoLP, pure specular, sigma 0.2, theta_r = {theta_r}:")
    print(f"  {'material':12s} {'th_i':>5s} {'beta':>6s} {'eq9':>9s} {'render':>9s} {'diff':>10s}")
    for name, n, k in mats:
        for ti in thetas:
            s0, s1, s2 = render_stokes([(_bsdf(_plate(n, k, 0.2)), [0, 0, 32, 32])], 32, 32, ti, theta_r, 4)
            m = [region_mean(a, [8, 8, 16, 16]) for a in (s0, s1, s2)]
            dolp, _ = dolp_aolp(*m)
            beta = beta_of(math.radians(ti), math.radians(theta_r))
            p9 = dop_eq9(n, k, beta)
            worst = max(worst, abs(dolp - p9))
            print(f"  {name:12s} {ti:5.1f} {math.degrees(beta):6.2f} {p9:9.6f} {dolp:9.6f} {dolp - p9:+10.2e}")
    print(f"  max |diff| = {worst:.2e}")
    return worst


def check_diffuse(theta_r=60.0) -> float:
    """Blend: DoLP = eq9 * (S0 - Ld) / S0 with Ld = w rho cos(theta_i) / pi; pure diffuse: 0."""
    p = _plate(1.39, 0.34, 0.2, 0.3)
    cal = calibrate_diffuse(p, theta_r)
    p.diffuse_weight = cal["weight"]
    p.diffuse_peak_radiance = cal["diffuse_peak_radiance_unit_weight"]
    worst = 0.0
    print(f"paint + diffuse (30% at the peak, blend weight {p.diffuse_weight:.4f}):")
    for ti in (35, 60, 80):
        s0, s1, s2 = render_stokes([(_bsdf(p), [0, 0, 32, 32])], 32, 32, ti, theta_r, 4)
        m = [region_mean(a, [8, 8, 16, 16]) for a in (s0, s1, s2)]
        dolp, _ = dolp_aolp(*m)
        beta = beta_of(math.radians(ti), math.radians(theta_r))
        # the diffuse part alone, same film and samples (spectral variants sample
        # wavelengths: absolute radiances carry ~1% noise there, ratios do not)
        d0, _, _ = render_stokes([(_bsdf(p, part="diffuse"), [0, 0, 32, 32])], 32, 32, ti, theta_r, 4)
        ld = p.diffuse_weight * region_mean(d0, [8, 8, 16, 16])
        ld_formula = diffuse_radiance(p, math.radians(ti), math.radians(theta_r))
        worst = max(worst, abs(ld_formula / ld - 1) if "mono" in mi.variant() else 0.0)
        exp = dop_eq9(p.n, p.k, beta) * (m[0] - ld) / m[0]
        worst = max(worst, abs(dolp - exp))
        print(f"  theta_i {ti:4.1f}: diffuse share {ld / m[0]:.4f}  expected DoLP {exp:.6f}  rendered {dolp:.6f}")
    s0, s1, s2 = render_stokes([(_bsdf(p, part="diffuse"), [0, 0, 32, 32])], 32, 32, 45, theta_r, 4)
    m = [region_mean(a, [8, 8, 16, 16]) for a in (s0, s1, s2)]
    pd, _ = dolp_aolp(*m)
    print(f"  pure Lambertian: DoLP {pd:.2e}, radiance {m[0]:.6f} (rho cos(45)/pi = "
          f"{p.diffuse_albedo * math.cos(math.radians(45)) / math.pi:.6f}; spectral variants differ by "
          f"their unit-spectrum RGB normalisation)")
    return max(worst, pd)


def cmd_verify(args):
    variant = init_mitsuba(args.variant)
    import mitsuba as _m

    print(f"mitsuba {_m.__version__}, variant {variant}")
    ok = check_brewster()
    for r in (30.0, -30.0, 60.0):
        ok &= check_roll(r)
    w9 = check_eq9(60.0)
    w9 = max(w9, check_eq9(50.0, (35, 80)))
    wd = check_diffuse()
    ok &= w9 < 1e-3 and wd < 1e-3
    print("verify:", "OK" if ok else "FAIL")
    sys.exit(0 if ok else 1)


def cmd_smoke(args):
    variant = init_mitsuba(args.variant)
    import mitsuba as _m

    print(f"mitsuba {_m.__version__}, variant {variant}")
    sys.exit(0 if check_brewster() else 1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("render", help="render a scene TOML into a capture set directory")
    r.add_argument("scene")
    r.add_argument("-o", "--output", required=True)
    r.add_argument("--variant", default="auto")
    r.add_argument("--force", action="store_true", help="replace an existing output directory")
    r.add_argument("--quiet", action="store_true")
    c = sub.add_parser("check", help="re-measure a rendered capture set against its truth.json")
    c.add_argument("dir")
    v = sub.add_parser("verify", help="Stokes convention and eq. (9) checks")
    v.add_argument("--variant", default="auto")
    s = sub.add_parser("smoke", help="quick Brewster-angle check")
    s.add_argument("--variant", default="auto")
    args = ap.parse_args()
    {"render": cmd_render, "check": cmd_check, "verify": cmd_verify, "smoke": cmd_smoke}[args.cmd](args)


if __name__ == "__main__":
    main()
