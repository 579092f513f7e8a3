#!/usr/bin/env python3
"""Independent polarized renders of a calibrated lamp-and-lens bench with Mitsuba 3.

A pinhole camera with OpenCV intrinsics looks at material plates lying on one or more
planes; a point lamp at a finite distance is moved between captures, in and out of the
camera's plane of incidence. Every pixel therefore has its own incidence angle, view
angle, azimuth and beta (paper eq. 5). Writes polarid capture sets in the
CALIBRATED-GEOMETRY manifest format (docs/FORMATS.md, "Calibrated geometry"):
rotating-polarizer frames, DoFP raw mosaics, ideal float32 Stokes images, a plate label
image, far-field manifest variants for comparison, and the ground truth.

Subcommands (see tools/render/README.md):

    render_bench.py render BENCH.toml --wavelength 450 -o OUTDIR [--variant V] [--force]
    render_bench.py check OUTDIR      # re-measure the files; per-pixel eq. (9) and projection
    render_bench.py verify-bench      # sensor / projection / Stokes-frame / eq. (9) checks
    render_bench.py reference OUTDIR [--dofp] [--map 4]   # numpy per-pixel fits (a yardstick)

Geometry is computed here in Python (numpy), independently of polarid's Rust code:
the OpenCV pinhole model, ray-plane intersections, the angles of docs/CONVENTIONS.md
("Calibrated geometry") and eq. (5). Mitsuba renders the images; the checks compare the
two.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import sys
import time
import tomllib
from dataclasses import dataclass, field

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import render_plates as rp  # noqa: E402  (shared Mitsuba set-up, physics and sensor model)

ANGLES = rp.ANGLES

# ----------------------------------------------------------------------------------------
# Camera and geometry (numpy; docs/CONVENTIONS.md "Calibrated geometry")
# ----------------------------------------------------------------------------------------


def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


@dataclass
class Camera:
    """OpenCV pinhole camera without distortion: pixel centres at integers, camera
    coordinates R (P - C) with R's rows the camera axes (x along columns, y along rows,
    z forward)."""

    fx: float
    fy: float
    cx: float
    cy: float
    position: np.ndarray
    R: np.ndarray
    look_at: np.ndarray
    up: np.ndarray

    @staticmethod
    def from_look_at(fx, fy, cx, cy, position, look_at, up) -> "Camera":
        c = np.asarray(position, float)
        z = unit(np.asarray(look_at, float) - c)
        u = np.asarray(up, float)
        y = -(u - u.dot(z) * z)
        if np.linalg.norm(y) < 1e-9:
            raise SystemExit("camera: up is parallel to the viewing direction")
        y = unit(y)
        x = np.cross(y, z)
        return Camera(fx, fy, cx, cy, c, np.stack([x, y, z]), np.asarray(look_at, float), u)

    def project(self, p) -> np.ndarray:
        """Pixel (u, v) of scene points p (..., 3)."""
        q = (np.asarray(p, float) - self.position) @ self.R.T
        return np.stack([self.fx * q[..., 0] / q[..., 2] + self.cx, self.fy * q[..., 1] / q[..., 2] + self.cy], -1)

    def rays(self, u, v) -> np.ndarray:
        """Unit scene-frame directions of the rays through pixels (u, v)."""
        u, v = np.broadcast_arrays(np.asarray(u, float), np.asarray(v, float))
        d = np.stack([(u - self.cx) / self.fx, (v - self.cy) / self.fy, np.ones_like(u)], -1)
        return unit(d @ self.R)

    def image_angle(self, point, direction) -> np.ndarray:
        """Image angle (deg, [0, 180), from +x towards -y as displayed) of the line the
        scene point `point` traces when it moves along `direction` (central projection)."""
        q = (np.asarray(point, float) - self.position) @ self.R.T
        w = np.asarray(direction, float) @ self.R.T
        x, y = q[..., 0] / q[..., 2], q[..., 1] / q[..., 2]
        du = self.fx * (w[..., 0] - x * w[..., 2])
        dv = self.fy * (w[..., 1] - y * w[..., 2])
        return np.degrees(np.arctan2(-dv, du)) % 180.0


@dataclass
class Plane:
    name: str
    point: np.ndarray
    normal: np.ndarray


@dataclass
class Plate:
    name: str
    cls: str
    plane: str
    center: np.ndarray
    size: tuple
    sigma: float
    n: float
    k: float
    reference: str
    x_axis: np.ndarray = None  # unit, in the plane
    y_axis: np.ndarray = None  # normal x x_axis
    normal: np.ndarray = None
    region: list = field(default_factory=list)
    pixels: int = 0

    @property
    def alpha(self) -> float:
        return math.sqrt(2.0) * self.sigma

    def corners(self) -> np.ndarray:
        a, b = self.size[0] / 2, self.size[1] / 2
        return np.array([self.center + sa * a * self.x_axis + sb * b * self.y_axis
                         for sa, sb in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


@dataclass
class Bench:
    name: str
    wavelength_nm: float
    camera: Camera
    planes: list
    plates: list
    lamps: list  # scene-frame positions
    lamp_specs: list
    width: int = 640
    height: int = 480
    spp: int = 16
    seed: int = 1
    file_format: str = "tif"
    margin_px: int = 6
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

    def plane(self, name) -> Plane:
        return next(p for p in self.planes if p.name == name)


def _fail(path, msg):
    raise SystemExit(f"{path}: {msg}")


def _vec3(path, what, v):
    if not (isinstance(v, list) and len(v) == 3 and all(isinstance(x, (int, float)) for x in v)):
        _fail(path, f"{what} must be three numbers, got {v!r}")
    return np.array(v, dtype=np.float64)


def load_bench(path: str, wavelength: float) -> Bench:
    """Read a bench TOML (format in README.md) for one wavelength band."""
    with open(path, "rb") as f:
        try:
            d = tomllib.load(f)
        except tomllib.TOMLDecodeError as e:
            _fail(path, f"invalid TOML: {e}")
    known = {"name", "spp", "seed", "file_format", "margin_px", "image", "camera", "sensor", "plane", "plate", "lamp"}
    for key in d:
        if key not in known:
            _fail(path, f"unknown key {key!r}")
    for req in ("name", "camera", "plate", "lamp"):
        if req not in d:
            _fail(path, f"missing key {req!r}")
    cam = d["camera"]
    f = cam["focal_px"]
    fx, fy = (float(f), float(f)) if isinstance(f, (int, float)) else (float(f[0]), float(f[1]))
    if fx != fy:
        _fail(path, f"camera.focal_px: Mitsuba's perspective sensor has square pixels, need fx = fy, got {f}")
    cx, cy = (float(v) for v in cam["principal_point_px"])
    camera = Camera.from_look_at(fx, fy, cx, cy, _vec3(path, "camera.position", cam["position"]),
                                 _vec3(path, "camera.look_at", cam["look_at"]), _vec3(path, "camera.up", cam["up"]))
    planes = [Plane(str(p["name"]), _vec3(path, "plane.point", p["point"]), unit(_vec3(path, "plane.normal", p["normal"])))
              for p in d.get("plane", [{"name": "default", "point": [0, 0, 0], "normal": [0, 0, 1]}])]
    if len({p.name for p in planes}) != len(planes):
        _fail(path, "plane names must be unique")
    key = f"{wavelength:g}"
    plates = []
    for i, p in enumerate(d["plate"]):
        for req in ("name", "center", "size", "sigma", "nk"):
            if req not in p:
                _fail(path, f"[[plate]] #{i + 1}: missing key {req!r}")
        if key not in p["nk"]:
            _fail(path, f"plate {p['name']!r}: no nk for wavelength {key} nm (have {sorted(p['nk'])})")
        n, k = (float(v) for v in p["nk"][key])
        pl = Plate(name=str(p["name"]), cls=str(p.get("class", p["name"])), plane=str(p.get("plane", planes[0].name)),
                   center=_vec3(path, "plate.center", p["center"]), size=tuple(float(s) for s in p["size"]),
                   sigma=float(p["sigma"]), n=n, k=k, reference=str(p.get("reference", "")))
        if pl.plane not in {q.name for q in planes}:
            _fail(path, f"plate {pl.name!r}: unknown plane {pl.plane!r}")
        if not (pl.n > 0 and pl.k >= 0 and 0 < pl.sigma < 1.5):
            _fail(path, f"plate {pl.name!r}: need n > 0, k >= 0, 0 < sigma < 1.5")
        pn = next(q for q in planes if q.name == pl.plane)
        if abs((pl.center - pn.point) @ pn.normal) > 1e-9:
            _fail(path, f"plate {pl.name!r}: center is not on plane {pl.plane!r}")
        xa = np.asarray(p.get("x_axis", [1.0, 0.0, 0.0]), float)
        xa = xa - (xa @ pn.normal) * pn.normal
        pl.normal = pn.normal
        pl.x_axis = unit(xa)
        pl.y_axis = np.cross(pn.normal, pl.x_axis)
        plates.append(pl)
    if len({p.name for p in plates}) != len(plates):
        _fail(path, "plate names must be unique")
    lamps, specs = [], []
    for i, l in enumerate(d["lamp"]):
        if "position" in l:
            pos = _vec3(path, f"lamp #{i + 1} position", l["position"])
        else:
            r, z, a = float(l["distance"]), math.radians(l["zenith_deg"]), math.radians(l["azimuth_deg"])
            # rounded to 1 um so that the manifests' positions are exactly the rendered ones
            pos = np.round(r * np.array([math.sin(z) * math.cos(a), math.sin(z) * math.sin(a), math.cos(z)]), 6)
        lamps.append(pos)
        specs.append(dict(l))
    img = d.get("image", {})
    b = Bench(name=f"{d['name']}_{key}", wavelength_nm=float(wavelength), camera=camera, planes=planes,
              plates=plates, lamps=lamps, lamp_specs=specs,
              width=int(img.get("width", 640)), height=int(img.get("height", 480)))
    for k2 in ("spp", "seed", "file_format", "margin_px"):
        if k2 in d:
            setattr(b, k2, d[k2])
    b.seed = int(b.seed) * 1000 + int(round(wavelength))
    for k2 in ("electrons_per_dn", "read_noise_dn", "dark_level", "bits", "full_scale_fraction", "exposure",
               "dofp_pattern"):
        if k2 in d.get("sensor", {}):
            setattr(b, k2, d["sensor"][k2])
    if b.file_format not in ("tif", "png"):
        _fail(path, f"file_format must be 'tif' or 'png', got {b.file_format!r}")
    if sorted(b.dofp_pattern) != [0, 45, 90, 135]:
        _fail(path, f"dofp_pattern must be a permutation of 0,45,90,135, got {b.dofp_pattern}")
    for pl in planes:
        if (camera.position - pl.point) @ pl.normal <= 0:
            _fail(path, f"the camera is not in front of plane {pl.name!r}")
        for i, L in enumerate(lamps):
            if (L - pl.point) @ pl.normal <= 0:
                _fail(path, f"lamp #{i + 1} is below plane {pl.name!r}")
    return b


def pixel_grid(b: Bench):
    """Pixel-centre coordinates (u, v) of the whole image, each H x W."""
    return np.meshgrid(np.arange(b.width, dtype=np.float64), np.arange(b.height, dtype=np.float64))


def trace(b: Bench, u, v):
    """Ray-cast pixels (u, v) against the plates.

    Returns (label, X, normal): label = plate index + 1 (0 = background), the hit point
    and the plate's normal (NaN where nothing is hit). The nearest plate wins.
    """
    d = b.camera.rays(u, v)
    C = b.camera.position
    best = np.full(d.shape[:-1], np.inf)
    label = np.zeros(d.shape[:-1], np.int32)
    X = np.full(d.shape, np.nan)
    N = np.full(d.shape, np.nan)
    for i, p in enumerate(b.plates):
        denom = d @ p.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((p.center - C) @ p.normal) / denom
        P = C + t[..., None] * d
        rel = P - p.center
        s, q = rel @ p.x_axis, rel @ p.y_axis
        hit = (t > 0) & (denom < 0) & (np.abs(s) <= p.size[0] / 2) & (np.abs(q) <= p.size[1] / 2) & (t < best)
        best = np.where(hit, t, best)
        label = np.where(hit, i + 1, label)
        X = np.where(hit[..., None], P, X)
        N = np.where(hit[..., None], p.normal, N)
    return label, X, N


def angles_at(X, N, lamp, cam_pos):
    """theta_i, theta_r, phi, beta (radians) at scene points X with normals N
    (docs/CONVENTIONS.md): u_i towards the lamp, u_r towards the camera; phi from the
    source's projection to the camera's, counter-clockwise about N, in [0, 2 pi);
    beta from eq. (5) and, as a cross-check, as half the angle between u_i and u_r."""
    ui = unit(lamp - X)
    ur = unit(cam_pos - X)
    ci, cr = np.sum(N * ui, -1), np.sum(N * ur, -1)
    ti, tr = np.arccos(np.clip(ci, -1, 1)), np.arccos(np.clip(cr, -1, 1))
    ai = ui - ci[..., None] * N
    ar = ur - cr[..., None] * N
    phi = np.arctan2(np.sum(N * np.cross(ai, ar), -1), np.sum(ai * ar, -1)) % (2 * np.pi)
    c2b = np.cos(ti) * np.cos(tr) + np.sin(ti) * np.sin(tr) * np.cos(phi)  # eq. (5)
    beta = 0.5 * np.arccos(np.clip(c2b, -1, 1))
    beta_direct = 0.5 * np.arccos(np.clip(np.sum(ui * ur, -1), -1, 1))
    return ti, tr, phi, beta, beta_direct, ui, ur


def shadowed(b: Bench, X, label, lamp):
    """True where the segment from the hit point X (plate label > 0) to the lamp crosses
    another plate (Mitsuba would render it dark; the bench is laid out to avoid it)."""
    out = np.zeros(label.shape, bool)
    d = lamp - X
    for i, p in enumerate(b.plates):
        denom = d @ p.normal
        with np.errstate(divide="ignore", invalid="ignore"):
            t = ((p.center - X) @ p.normal) / denom
        P = X + t[..., None] * d
        rel = P - p.center
        hit = (label != i + 1) & (label > 0) & (t > 1e-9) & (t < 1) & (np.abs(rel @ p.x_axis) <= p.size[0] / 2) \
            & (np.abs(rel @ p.y_axis) <= p.size[1] / 2)
        out |= hit
    return out


def dop_eq9_array(n, k, beta):
    """Paper eq. (9), vectorized (beta in radians)."""
    s, c = np.sin(beta), np.cos(beta)
    dd = n * n - k * k - s * s
    cc = np.sqrt(4 * n * n * k * k + dd * dd)
    a = np.sqrt((cc + dd) / 2)
    bb = np.sqrt(np.maximum((cc - dd) / 2, 0.0))
    return 2 * a * s * s * c / (a * a * c * c + s**4 + bb * bb * c * c)


def mitsuba_stokes_angle(b: Bench, d, s_dir):
    """Angle (deg, [0, 180)) of the linear polarization direction s_dir in the Stokes
    frame of Mitsuba's `stokes` integrator for a camera ray d: first axis d x up_img
    (up_img = the camera's -y axis, image up), second axis (first) x d. For rays on
    the optical axis this is the image's +x / up frame; off axis it differs from the
    central projection (Camera.image_angle) by up to a few degrees (second order in the
    field angles)."""
    up_img = -b.camera.R[1]
    b1 = unit(np.cross(d, up_img))
    b2 = np.cross(b1, d)
    return np.degrees(np.arctan2(np.sum(s_dir * b2, -1), np.sum(s_dir * b1, -1))) % 180.0


def largest_rect(mask: np.ndarray):
    """Largest axis-aligned rectangle of True pixels: (x, y, w, h) (histogram method)."""
    H, W = mask.shape
    heights = np.zeros(W, int)
    best = (0, 0, 0, 0, 0)
    for r in range(H):
        heights = np.where(mask[r], heights + 1, 0)
        stack = []
        for c in range(W + 1):
            h = heights[c] if c < W else 0
            start = c
            while stack and stack[-1][1] >= h:
                s, sh = stack.pop()
                area = sh * (c - s)
                if area > best[0]:
                    best = (area, s, r - sh + 1, c - s, sh)
                start = s
            stack.append((start, h))
    _, x, y, w, h = best
    return x, y, w, h


def region_rect(label: np.ndarray, idx: int, margin: int):
    """Plate interior: the largest rect of the plate's pixels eroded by `margin`, with
    even x, y, width and height (whole DoFP super-pixels)."""
    m = label == idx
    er = m.copy()
    for dy in range(-margin, margin + 1):
        for dx in range(-margin, margin + 1):
            er &= np.roll(np.roll(m, dy, 0), dx, 1)
    x, y, w, h = largest_rect(er)
    x2, y2 = x + (x % 2), y + (y % 2)
    w2, h2 = (x + w - x2) // 2 * 2, (y + h - y2) // 2 * 2
    return [int(x2), int(y2), int(w2), int(h2)]


# ----------------------------------------------------------------------------------------
# Mitsuba scene
# ----------------------------------------------------------------------------------------


def sensor_dict(b: Bench, spp: int, film_extra=None) -> dict:
    """Mitsuba `perspective` sensor matching the OpenCV camera.

    Mitsuba's camera space is x left, y up, z forward, so its to_world columns are
    (-x_cv, -y_cv, z_cv, C). Film pixel (i, j) covers [i, i+1) x [j, j+1) (centre
    i + 0.5), i.e. OpenCV column u = i: the principal point (cx, cy) lies at film position
    (cx + 0.5, cy + 0.5). Mitsuba puts it at (W/2 - ox W, H/2 - oy H) for
    principal_point_offset_x/y = ox, oy (measured with Sensor.sample_ray, see
    verify-bench), so ox = ((W - 1)/2 - cx)/W, oy = ((H - 1)/2 - cy)/H. The
    horizontal field of view is 2 atan(W / (2 fx)).
    """
    c = b.camera
    T = rp.mi.ScalarTransform4f
    M = np.eye(4)
    M[:3, 0], M[:3, 1], M[:3, 2], M[:3, 3] = -c.R[0], -c.R[1], c.R[2], c.position
    film = {"type": "hdrfilm", "width": b.width, "height": b.height, "rfilter": {"type": "box"}}
    film.update(film_extra or {})
    return {
        "type": "perspective",
        "fov": 2 * math.degrees(math.atan(b.width / (2 * c.fx))),
        "fov_axis": "x",
        "principal_point_offset_x": ((b.width - 1) / 2 - c.cx) / b.width,
        "principal_point_offset_y": ((b.height - 1) / 2 - c.cy) / b.height,
        "near_clip": 0.01,
        "far_clip": 100.0,
        "to_world": T(M.tolist()),
        "film": film,
        "sampler": {"type": "stratified", "sample_count": spp},
    }


def plate_shape(p: Plate, bsdf: dict) -> dict:
    """Mitsuba `rectangle` ([-1, 1]^2 in z = 0, normal +z) mapped onto the plate."""
    T = rp.mi.ScalarTransform4f
    M = np.eye(4)
    M[:3, 0] = p.x_axis * p.size[0] / 2
    M[:3, 1] = p.y_axis * p.size[1] / 2
    M[:3, 2] = p.normal
    M[:3, 3] = p.center
    return {"type": "rectangle", "to_world": T(M.tolist()), "bsdf": bsdf}


def plate_bsdf(p: Plate) -> dict:
    return {"type": "roughconductor", "distribution": "beckmann", "alpha": p.alpha, "eta": p.n, "k": p.k}


def render_capture(b: Bench, lamp, spp: int):
    """S0, S1, S2 (H x W float64, Mitsuba's Stokes frame; see mitsuba_stokes_angle) lit
    by an unpolarized point lamp of intensity 1 W/sr at `lamp`."""
    scene = {
        "type": "scene",
        "integrator": {"type": "stokes", "integrator": {"type": "direct"}},
        "sensor": sensor_dict(b, spp),
        "lamp": {"type": "point", "position": [float(x) for x in lamp], "intensity": {"type": "spectrum", "value": 1.0}},
    }
    for i, p in enumerate(b.plates):
        scene[f"plate{i}"] = plate_shape(p, plate_bsdf(p))
    sc = rp.mi.load_dict(scene)
    rp.mi.render(sc, seed=0)
    ch = {name: np.array(bm, dtype=np.float64) for name, bm in sc.sensors()[0].film().bitmap().split()}
    return tuple(ch[c].mean(axis=2) if ch[c].ndim == 3 else ch[c] for c in ("S0", "S1", "S2"))


def marker_points(b: Bench) -> list:
    """Known scene points for the projection check: every plate's centre and corners
    (moved 5 mm inwards) and points off the planes spread over the field."""
    pts = []
    for p in b.plates:
        pts.append((f"{p.name}.center", p.center))
        for j, c in enumerate(p.corners()):
            pts.append((f"{p.name}.corner{j}", c + 0.005 * unit(p.center - c)))
    c = b.camera
    # Points 0.6-0.9 m in front of the camera towards the image corners and edges.
    for j, (u, v, t) in enumerate([(30, 25, 0.7), (610, 30, 0.85), (25, 455, 0.65), (615, 450, 0.9),
                                   (320, 20, 0.75), (320, 462, 0.8), (15, 240, 0.7), (625, 240, 0.72)]):
        pts.append((f"field{j}", c.position + t * c.rays(u + 0.3, v - 0.2)))
    return pts


def render_markers(b: Bench, spp: int = 64):
    """Render small emitting disks (radius 1.5 mm, facing the camera) at the marker
    points; return [(name, point, centroid (u, v) in OpenCV pixels, flux)]."""
    T = rp.mi.ScalarTransform4f
    pts = marker_points(b)
    scene = {"type": "scene", "integrator": {"type": "direct"}, "sensor": sensor_dict(b, spp)}
    for j, (_, P) in enumerate(pts):
        n = unit(b.camera.position - P)
        a = unit(np.cross(n, [0.0, 0.0, 1.0]) if abs(n[2]) < 0.9 else np.cross(n, [1.0, 0.0, 0.0]))
        c2 = np.cross(n, a)
        r = 0.0015
        M = np.eye(4)
        M[:3, 0], M[:3, 1], M[:3, 2], M[:3, 3] = a * r, c2 * r, n, P
        scene[f"m{j}"] = {"type": "disk", "to_world": T(M.tolist()),
                          "emitter": {"type": "area", "radiance": {"type": "spectrum", "value": 1.0}}}
    sc = rp.mi.load_dict(scene)
    img = np.array(rp.mi.render(sc, seed=1), dtype=np.float64)
    img = img[..., 0] if img.ndim == 3 else img
    out = []
    predicted = b.camera.project(np.array([P for _, P in pts]))
    for (name, P), (pu, pv) in zip(pts, predicted):
        # the blob near the predicted pixel (radius ~1.7 px); window +-6 px
        u0, v0 = int(round(pu)), int(round(pv))
        ys, xs = slice(max(v0 - 6, 0), min(v0 + 7, b.height)), slice(max(u0 - 6, 0), min(u0 + 7, b.width))
        w = img[ys, xs]
        vv, uu = np.mgrid[ys, xs]
        tot = float(w.sum())
        cu, cv = float((w * uu).sum() / tot), float((w * vv).sum() / tot)
        border = float(w[0].sum() + w[-1].sum() + w[:, 0].sum() + w[:, -1].sum())
        if not (tot > 0 and border == 0):
            raise SystemExit(f"marker {name}: no isolated blob near the predicted pixel ({pu:.1f}, {pv:.1f})")
        out.append({"name": name, "point": [float(x) for x in P], "rendered_px": [cu, cv],
                    "python_projection_px": [float(pu), float(pv)], "flux": tot})
    return out


# ----------------------------------------------------------------------------------------
# Files
# ----------------------------------------------------------------------------------------


def _f(x) -> str:
    return repr(float(x))


def _v(v) -> str:
    return "[" + ", ".join(_f(x) for x in v) + "]"


def write_manifests(tmp: str, b: Bench, captures: list):
    """Calibrated manifests (frames, DoFP, ideal Stokes) and the far-field variants."""
    c = b.camera
    head = [
        f"wavelength_nm = {b.wavelength_nm:.1f}",
        "",
        "[camera]",
        f"focal_px = {_v([c.fx, c.fy])}",
        f"principal_point_px = {_v([c.cx, c.cy])}",
        f"position = {_v(c.position)}",
        f"look_at = {_v(c.look_at)}",
        f"up = {_v(c.up)}",
    ]
    for pl in b.planes:
        head += ["", "[[plane]]", f'name = "{pl.name}"', f"point = {_v(pl.point)}", f"normal = {_v(pl.normal)}"]
    for p in b.plates:
        head += ["", "[[region]]", f'name = "{p.name}"', f"rect = {p.region}", f'class = "{p.cls}"',
                 f'plane = "{p.plane}"']

    def capture_lines(cap, kind, angles=None):
        d = cap["dir"]
        lines = ["", "[[capture]]", f'name = "{cap["name"]}"']
        if angles is None:
            lines.append(f"source = {{ position = {_v(cap['lamp'])} }}")
        else:
            ti, tr, phi = angles
            lines += [f"theta_i_deg = {_f(ti)}", f"theta_r_deg = {_f(tr)}", f"phi_deg = {_f(phi)}"]
        if kind == "frames":
            lines.append(f"exposure = {cap['exposure']:.9g}")
            lines.append("frames = [")
            for a in ANGLES:
                lines.append(f'  {{ angle_deg = {a:.1f}, file = "{d}/pol{a:03d}.{b.file_format}" }},')
            lines.append("]")
        elif kind == "dofp":
            lines.append(f"exposure = {cap['exposure']:.9g}")
            pat = ", ".join(str(int(a)) for a in b.dofp_pattern)
            lines.append(f'dofp = {{ file = "{d}/raw.{b.file_format}", pattern = [{pat}] }}')
        else:
            lines.append(f'stokes = {{ s0 = "ideal/{d}/s0.tif", s1 = "ideal/{d}/s1.tif", s2 = "ideal/{d}/s2.tif" }}')
        return lines

    for kind, fname in (("frames", "manifest.toml"), ("dofp", "manifest_dofp.toml"), ("stokes", "manifest_stokes.toml")):
        lines = [f"# polarid capture set rendered by tools/render/render_bench.py (Mitsuba 3), bench {b.name!r}",
                 f"# {kind} captures, calibrated geometry (docs/FORMATS.md); ground truth in truth.json",
                 f"dark_level = {float(b.dark_level) if kind != 'stokes' else 0.0:.1f}"]
        if kind != "stokes":
            lines.append(f"saturation = {b.saturation:.1f}")
        lines += head
        for cap in captures:
            lines += capture_lines(cap, kind)
        with open(os.path.join(tmp, fname), "w") as f:
            f.write("\n".join(lines) + "\n")

    # Far-field variants (frames): one angle set per capture, as the paper's idealisation.
    def farfield(path, comment, regions, angle_key):
        lines = [f"# far-field variant of manifest.toml, bench {b.name!r}: {comment}",
                 "# (for comparison with the calibrated geometry; not the truth)",
                 f"dark_level = {float(b.dark_level):.1f}", f"saturation = {b.saturation:.1f}",
                 f"wavelength_nm = {b.wavelength_nm:.1f}"]
        for p in regions:
            lines += ["", "[[region]]", f'name = "{p.name}"', f"rect = {p.region}", f'class = "{p.cls}"']
        for cap in captures:
            g = cap[angle_key] if isinstance(angle_key, str) else angle_key(cap)
            lines += capture_lines(cap, "frames", (g["theta_i_deg"], g["theta_r_deg"], g["phi_deg"]))
        with open(path, "w") as f:
            f.write("\n".join(lines) + "\n")

    farfield(os.path.join(tmp, "farfield_center.toml"),
             "every region gets the angles at the camera's look_at point on the first plane", b.plates,
             "center_geometry")
    os.makedirs(os.path.join(tmp, "farfield"), exist_ok=True)
    for p in b.plates:
        farfield(os.path.join(tmp, "farfield", f"{p.name}.toml"),
                 f"region {p.name!r} alone, with the angles at its centre pixel", [p],
                 lambda cap, p=p: cap["plates"][p.name]["center_pixel"])
    # far-field manifests in farfield/ refer to ../ files
    for p in b.plates:
        fp = os.path.join(tmp, "farfield", f"{p.name}.toml")
        with open(fp) as f:
            txt = f.read()
        with open(fp, "w") as f:
            f.write(txt.replace('file = "', 'file = "../'))


def _geometry_record(ti, tr, phi, beta):
    return {"theta_i_deg": float(np.degrees(ti)), "theta_r_deg": float(np.degrees(tr)),
            "phi_deg": float(np.degrees(phi)), "beta_deg": float(np.degrees(beta))}


# ----------------------------------------------------------------------------------------
# render
# ----------------------------------------------------------------------------------------


def cmd_render(args):
    b = load_bench(args.bench, args.wavelength)
    variant = rp.init_mitsuba(args.variant)
    if "mono" not in variant:
        print(f"warning: variant {variant}: the bench renders are meant for a mono variant", file=sys.stderr)
    out = os.path.abspath(args.output)
    if os.path.exists(out) and not args.force:
        raise SystemExit(f"{out} exists (use --force to replace it)")
    tmp = out + ".partial"
    shutil.rmtree(tmp, ignore_errors=True)
    os.makedirs(tmp)
    t0 = time.time()
    cam = b.camera

    # Geometry of every pixel centre (Python, independent of polarid).
    U, V = pixel_grid(b)
    label, X, N = trace(b, U, V)
    for i, p in enumerate(b.plates):
        p.pixels = int((label == i + 1).sum())
        if p.pixels == 0:
            raise SystemExit(f"{args.bench}: plate {p.name!r} is not in the image")
        p.region = region_rect(label, i + 1, int(b.margin_px))
        if p.region[2] < 16 or p.region[3] < 16:
            raise SystemExit(f"{args.bench}: plate {p.name!r}: interior region {p.region} is too small")
    on = label > 0
    import tifffile

    tifffile.imwrite(os.path.join(tmp, "labels.tif"), label.astype(np.uint8))

    renders = []
    for j, L in enumerate(b.lamps):
        t = time.time()
        s0, s1, s2 = render_capture(b, L, int(b.spp))
        renders.append((s0, s1, s2))
        if not args.quiet:
            print(f"  lamp {j + 1}/{len(b.lamps)} at {np.round(L, 3)}: rendered in {time.time() - t:.1f} s",
                  file=sys.stderr)
    t_render = time.time() - t0
    t = time.time()
    markers = render_markers(b)
    t_markers = time.time() - t

    # Exposure (as render_plates.py): per capture, the brightest plate pixel of any
    # polarizer frame at full_scale_fraction of the range above the dark level.
    full = b.saturation - float(b.dark_level)
    peaks = [max(float(rp.polarizer(s0, s1, s2, a)[on].max()) for a in ANGLES) for s0, s1, s2 in renders]
    for j, pk in enumerate(peaks):
        if not pk > 0:
            shutil.rmtree(tmp, ignore_errors=True)
            raise SystemExit(f"{args.bench}: every plate is black for lamp #{j + 1}")
    if b.exposure == "auto":
        gains = [b.full_scale_fraction * full / pk for pk in peaks]
    elif b.exposure == "fixed":
        gains = [b.full_scale_fraction * full / max(peaks)] * len(peaks)
    else:
        gains = [float(b.exposure)] * len(peaks)
    g_ref = min(gains)

    rng = np.random.default_rng(b.seed)
    pat_ang = rp.dofp_angles(b.dofp_pattern, b.height, b.width)
    captures = []
    worst = {"eq9_pixel": 0.0, "aolp_mitsuba_frame_deg": 0.0, "beta_eq5_vs_direct_deg": 0.0}
    frame_rot_max = 0.0
    for j, ((s0, s1, s2), L, gain, peak) in enumerate(zip(renders, b.lamps, gains, peaks)):
        name = f"L{j + 1:02d}"
        d = name
        frames = {a: rp.polarizer(s0, s1, s2, a) for a in ANGLES}
        for a in ANGLES:
            rp.write_image(os.path.join(tmp, d, f"pol{a:03d}.{b.file_format}"), rp.expose(frames[a], gain, b, rng))
        mosaic = np.zeros_like(s0)
        for a in ANGLES:
            mosaic[pat_ang == a] = frames[a][pat_ang == a]
        rp.write_image(os.path.join(tmp, d, f"raw.{b.file_format}"), rp.expose(mosaic, gain, b, rng))
        os.makedirs(os.path.join(tmp, "ideal", d), exist_ok=True)
        for nm, img in (("s0", s0), ("s1", s1), ("s2", s2)):
            tifffile.imwrite(os.path.join(tmp, "ideal", d, f"{nm}.tif"), (img * g_ref).astype(np.float32))

        ti, tr, phi, beta, beta_d, ui, ur = angles_at(X, N, L, cam.position)
        shadow = shadowed(b, X, label, L)
        worst["beta_eq5_vs_direct_deg"] = max(worst["beta_eq5_vs_direct_deg"],
                                              float(np.nanmax(np.abs(np.degrees(beta - beta_d)))))
        lv = b.planes[0]
        cg = angles_at(cam.look_at[None], lv.normal[None], L, cam.position)
        spec = dict(b.lamp_specs[j])
        cap = {
            "name": name, "dir": d, "lamp": [float(x) for x in L], "lamp_spec": spec,
            "lamp_distance_to_look_at_m": float(np.linalg.norm(L - cam.look_at)),
            "gain_dn_per_radiance": gain, "exposure": gain / g_ref, "brightest_plate_dn": peak * gain,
            "center_geometry": _geometry_record(cg[0][0], cg[1][0], cg[2][0], cg[3][0]),
            "plates": {},
        }
        for i, p in enumerate(b.plates):
            x, y, w, h = p.region
            sl = (slice(y, y + h), slice(x, x + w))
            m = [float(a[sl].mean()) for a in (s0, s1, s2)]
            dolp, aolp = rp.dolp_aolp(*m) if m[0] > 0 else (float("nan"), float("nan"))
            wgt = s0[sl]
            bs = np.degrees(beta[sl])
            bmean = float((wgt * bs).sum() / wgt.sum()) if wgt.sum() > 0 else float("nan")
            bsd = float(math.sqrt(max((wgt * (bs - bmean) ** 2).sum() / wgt.sum(), 0.0))) if wgt.sum() > 0 else float("nan")
            # the DoLP the region would have if every pixel's own eq. (9) value were
            # averaged in its Stokes vector (S0-weighted, each pixel's AoLP kept)
            p9 = dop_eq9_array(p.n, p.k, beta[sl])
            ang = np.arctan2(s2[sl], s1[sl])
            ms1, ms2 = float((wgt * p9 * np.cos(ang)).sum()), float((wgt * p9 * np.sin(ang)).sum())
            forward = math.hypot(ms1, ms2) / float(wgt.sum()) if wgt.sum() > 0 else float("nan")
            uc, vc = x + (w - 1) / 2, y + (h - 1) / 2
            lc, Xc, Nc = trace(b, np.array([uc]), np.array([vc]))
            gc = angles_at(Xc, Nc, L, cam.position)
            cen = _geometry_record(gc[0][0], gc[1][0], gc[2][0], gc[3][0])
            cen["u"], cen["v"] = uc, vc
            cen["dolp_eq9"] = float(rp.dop_eq9(p.n, p.k, gc[3][0]))
            # Per-pixel checks: rendered ideal DoLP vs eq. (9) at the pixel centre's beta;
            # AoLP vs the s direction (u_i x u_r) in Mitsuba's Stokes frame.
            checks = []
            for fu, fv in ((0.5, 0.5), (0.15, 0.2), (0.85, 0.2), (0.15, 0.8), (0.85, 0.8)):
                pu, pv = int(round(x + fu * (w - 1))), int(round(y + fv * (h - 1)))
                if s0[pv, pu] <= 0:
                    continue
                dl, al = rp.dolp_aolp(s0[pv, pu], s1[pv, pu], s2[pv, pu])
                p9p = float(dop_eq9_array(p.n, p.k, beta[pv, pu]))
                sdir = unit(np.cross(ui[pv, pu], ur[pv, pu]))
                ray = cam.rays(np.array(float(pu)), np.array(float(pv)))
                a_mi = float(mitsuba_stokes_angle(b, ray, sdir))
                a_proj = float(cam.image_angle(X[pv, pu], sdir))
                # trace of the plane of incidence (polarid's poi_angle, central projection)
                wdir = ui[pv, pu] - (ui[pv, pu] @ ur[pv, pu]) * ur[pv, pu]
                a_poi = float(cam.image_angle(X[pv, pu], wdir))
                da = (al - a_mi + 90) % 180 - 90
                frame_rot = (a_proj - a_mi + 90) % 180 - 90
                worst["eq9_pixel"] = max(worst["eq9_pixel"], abs(dl - p9p))
                worst["aolp_mitsuba_frame_deg"] = max(worst["aolp_mitsuba_frame_deg"], abs(da))
                frame_rot_max = max(frame_rot_max, abs(frame_rot))
                rec = _geometry_record(ti[pv, pu], tr[pv, pu], phi[pv, pu], beta[pv, pu])
                rec.update({"u": pu, "v": pv, "dolp_rendered": dl, "dolp_eq9": p9p, "aolp_rendered_deg": al,
                            "s_direction_angle_mitsuba_frame_deg": a_mi, "s_direction_angle_projected_deg": a_proj,
                            "poi_angle_projected_deg": a_poi})
                checks.append(rec)
            cap["plates"][p.name] = {
                "region_s0_dn": m[0] * gain,
                "region_s0_per_exposure": m[0] * g_ref,
                "region_dolp": dolp,
                "region_aolp_deg": aolp,
                "region_dolp_pixelwise_eq9": forward,
                "beta_mean_deg": bmean,
                "beta_sd_deg": bsd,
                "beta_min_deg": float(bs.min()),
                "beta_max_deg": float(bs.max()),
                "theta_i_range_deg": [float(np.degrees(ti[sl]).min()), float(np.degrees(ti[sl]).max())],
                "theta_r_range_deg": [float(np.degrees(tr[sl]).min()), float(np.degrees(tr[sl]).max())],
                "phi_range_deg": [float(np.degrees(phi[sl]).min()), float(np.degrees(phi[sl]).max())],
                "region_s0_cv": float(s0[sl].std() / max(m[0], 1e-30)),
                "shadowed_plate_pixels": int((shadow & (label == i + 1)).sum()),
                "center_pixel": cen,
                "pixel_checks": checks,
            }
        captures.append(cap)
        if not args.quiet:
            print(f"  {name}: gain {gain:.4g}, " + ", ".join(
                f"{p.name} {cap['plates'][p.name]['region_s0_dn']:.0f} DN" for p in b.plates), file=sys.stderr)

    # Well-lit plates: region mean S0 >= 100 DN above the dark level in at least 6 captures.
    well_lit = {}
    for p in b.plates:
        lit = [c["name"] for c in captures if c["plates"][p.name]["region_s0_dn"] >= 100.0]
        well_lit[p.name] = {"captures_at_least_100_dn": lit, "well_lit": len(lit) >= 6}

    marker_err_py = max(math.hypot(m["rendered_px"][0] - m["python_projection_px"][0],
                                   m["rendered_px"][1] - m["python_projection_px"][1]) for m in markers)
    import mitsuba as _m

    truth = {
        "bench": b.name,
        "source_bench_file": os.path.abspath(args.bench),
        "wavelength_nm": b.wavelength_nm,
        "renderer": {
            "mitsuba": _m.__version__, "variant": variant, "spp": int(b.spp), "integrator": "stokes(direct)",
            "sensor": "perspective (pinhole), box filter", "emitter": "point, unpolarized, intensity 1 W/sr",
            "bsdf": "roughconductor, Beckmann, alpha = sqrt(2) sigma (k = 0 for the glass)",
            "render_seconds": round(t_render, 2), "marker_render_seconds": round(t_markers, 2),
        },
        "stokes_convention": "S1 = I(0) - I(90), S2 = I(45) - I(135); Mitsuba's stokes-integrator frame per "
                             "pixel ray d: first axis d x up_img (up_img = image up = -camera y), second axis "
                             "(first axis) x d; equal to the image +x/up frame on the optical axis. It differs "
                             "from the central projection of the polarization direction by up to "
                             f"{frame_rot_max:.2f} deg at the sampled plate pixels (DoLP is frame-independent)",
        "image": {"width": b.width, "height": b.height},
        "camera": {"focal_px": [cam.fx, cam.fy], "principal_point_px": [cam.cx, cam.cy],
                   "position": cam.position.tolist(), "look_at": cam.look_at.tolist(), "up": cam.up.tolist(),
                   "rotation_world_to_camera": cam.R.tolist(), "distortion": [0.0] * 5},
        "planes": [{"name": pl.name, "point": pl.point.tolist(), "normal": pl.normal.tolist()} for pl in b.planes],
        "sensor": {
            "bits": b.bits, "saturation_dn": b.saturation, "dark_level_dn": b.dark_level,
            "electrons_per_dn": b.electrons_per_dn, "read_noise_dn": b.read_noise_dn,
            "exposure_mode": b.exposure, "full_scale_fraction": b.full_scale_fraction,
            "reference_gain_dn_per_radiance": g_ref, "dofp_pattern": b.dofp_pattern, "seed": b.seed,
        },
        "plates": [
            {"name": p.name, "class": p.cls, "plane": p.plane, "n": p.n, "k": p.k,
             "nk_source": f"refractiveindex.info {p.reference} at {b.wavelength_nm:g} nm "
                          f"(polarid library --band {b.wavelength_nm:g}, data/materials/refractiveindex)",
             "sigma": p.sigma, "beckmann_alpha": p.alpha, "center": p.center.tolist(), "size_m": list(p.size),
             "x_axis": p.x_axis.tolist(), "y_axis": p.y_axis.tolist(), "normal": p.normal.tolist(),
             "corners": p.corners().tolist(), "label": i + 1, "pixels": p.pixels, "region": p.region,
             **well_lit[p.name]}
            for i, p in enumerate(b.plates)
        ],
        "labels_file": "labels.tif (uint8: 0 background, i + 1 = plates[i], from ray casting the pixel centres)",
        "projection_check": {"markers": markers, "max_error_vs_python_px": marker_err_py,
                             "note": "centroids of emitting disks (r 1.5 mm, facing the camera) rendered by "
                                     "Mitsuba, in OpenCV pixels (centres at integers)"},
        "checks": {"max_abs_dolp_minus_eq9_at_pixels": worst["eq9_pixel"],
                   "max_abs_aolp_minus_s_direction_deg": worst["aolp_mitsuba_frame_deg"],
                   "max_abs_beta_eq5_minus_half_angle_deg": worst["beta_eq5_vs_direct_deg"],
                   "max_abs_frame_rotation_projected_vs_mitsuba_deg": frame_rot_max},
        "captures": captures,
    }
    with open(os.path.join(tmp, "truth.json"), "w") as f:
        json.dump(truth, f, indent=1)
    with open(os.path.join(tmp, "truth_plates.csv"), "w") as f:
        f.write("# per plate: (n, k) truth at the band; well_lit = region S0 >= 100 DN in >= 6 captures\n")
        f.write("target,class,plane,n,k,sigma,well_lit,region_x,region_y,region_w,region_h\n")
        for p in b.plates:
            f.write(f"{p.name},{p.cls},{p.plane},{p.n:.10g},{p.k:.10g},{p.sigma:g},"
                    f"{str(well_lit[p.name]['well_lit']).lower()},{','.join(str(v) for v in p.region)}\n")
    write_manifests(tmp, b, captures)
    shutil.copy(args.bench, os.path.join(tmp, "bench.toml"))
    if os.path.exists(out):
        shutil.rmtree(out)
    os.rename(tmp, out)
    print(f"{b.name}: {len(renders)} captures, {b.width}x{b.height}, {b.spp} spp, variant {variant}, "
          f"render {t_render:.1f} s (+ markers {t_markers:.1f} s), total {time.time() - t0:.1f} s -> {out}")
    print(f"  checks: max |DoLP - eq9| at pixels {worst['eq9_pixel']:.2e}; max |AoLP - s direction| "
          f"{worst['aolp_mitsuba_frame_deg']:.3f} deg; max marker |rendered - projected| {marker_err_py:.3f} px")
    print("  well lit: " + ", ".join(f"{k} {'yes' if v['well_lit'] else 'NO'} ({len(v['captures_at_least_100_dn'])})"
                                     for k, v in well_lit.items()))


# ----------------------------------------------------------------------------------------
# check: re-measure a rendered set, geometry from its manifest
# ----------------------------------------------------------------------------------------


def camera_from_manifest(man) -> Camera:
    c = man["camera"]
    f = c["focal_px"]
    fx, fy = (f, f) if isinstance(f, (int, float)) else f
    return Camera.from_look_at(float(fx), float(fy), *map(float, c["principal_point_px"]), c["position"], c["look_at"],
                               c["up"])


def demosaic_bilinear(raw, pattern):
    """Each polarizer channel of a 2 x 2 DoFP mosaic interpolated bilinearly to full
    resolution (exact for linear intensity gradients; edges by replication)."""
    H, W = raw.shape
    k = np.array([0.25, 0.5, 1.0, 0.5, 0.25])[1:4]
    out = {}
    for idx, (oy, ox) in enumerate(((0, 0), (0, 1), (1, 0), (1, 1))):
        sparse = np.zeros((H + 2, W + 2))
        mask = np.zeros((H + 2, W + 2))
        sparse[1 + oy:H + 1:2, 1 + ox:W + 1:2] = raw[oy::2, ox::2]
        mask[1 + oy:H + 1:2, 1 + ox:W + 1:2] = 1.0
        acc = np.zeros((H, W))
        wsum = np.zeros((H, W))
        for dy in (-1, 0, 1):
            for dx in (-1, 0, 1):
                w = k[dy + 1] * k[dx + 1]
                acc += w * sparse[1 + dy:H + 1 + dy, 1 + dx:W + 1 + dx]
                wsum += w * mask[1 + dy:H + 1 + dy, 1 + dx:W + 1 + dx]
        out[int(pattern[idx])] = acc / wsum
    return out


def cmd_check(args):
    """Re-measure the files of a set: per-pixel eq. (9) on the ideal Stokes images with the
    geometry rebuilt from manifest.toml (not from the bench TOML), the projection markers,
    and the region DoLP of the noisy frames and DoFP mosaics against the ideal one."""
    root = os.path.abspath(args.dir)
    with open(os.path.join(root, "truth.json")) as f:
        truth = json.load(f)
    man = {}
    for kind, fn in (("frames", "manifest.toml"), ("dofp", "manifest_dofp.toml"), ("stokes", "manifest_stokes.toml")):
        with open(os.path.join(root, fn), "rb") as f:
            man[kind] = tomllib.load(f)
    cam = camera_from_manifest(man["frames"])
    planes = {p["name"]: (np.array(p["point"], float), unit(p["normal"])) for p in man["frames"]["plane"]}
    plates = {p["name"]: p for p in truth["plates"]}
    # projection: the rendered marker centroids vs the manifest camera
    err = max(math.dist(m["rendered_px"], cam.project(np.array(m["point"]))) for m in truth["projection_check"]["markers"])
    print(f"projection: {len(truth['projection_check']['markers'])} markers, max |rendered - projected| {err:.3f} px")
    dark = float(man["frames"].get("dark_level", 0.0))
    sat = float(man["frames"]["saturation"])
    worst = {"eq9": 0.0, "frames": 0.0, "dofp": 0.0, "z_frames": 0.0, "z_dofp": 0.0}
    n_rej = 0
    print(f"{'capture':7s} {'target':15s} {'S0 DN':>7s} {'ideal':>8s} {'frames':>8s} {'se':>7s} {'dofp':>8s} {'se':>7s} "
          f"{'beta':>6s} {'sd':>5s}")
    for cs, cf, cd, tc in zip(man["stokes"]["capture"], man["frames"]["capture"], man["dofp"]["capture"],
                              truth["captures"]):
        L = np.array(cs["source"]["position"], float)
        S = [rp.read_image(os.path.join(root, cs["stokes"][k])) for k in ("s0", "s1", "s2")]
        fr = {int(f_["angle_deg"]): rp.read_image(os.path.join(root, f_["file"])) for f_ in cf["frames"]}
        raw = rp.read_image(os.path.join(root, cd["dofp"]["file"]))
        pat = cd["dofp"]["pattern"]
        demo = demosaic_bilinear(raw - dark, pat)
        for reg in man["frames"]["region"]:
            x, y, w, h = reg["rect"]
            pt, nrm = planes[reg["plane"]]
            # every 4th pixel of the region: geometry from the manifest, eq. (9) vs ideal
            vv, uu = np.mgrid[y:y + h:4, x:x + w:4].astype(float)
            d = cam.rays(uu, vv)
            tt = ((pt - cam.position) @ nrm) / (d @ nrm)
            X = cam.position + tt[..., None] * d
            _, _, _, beta, _, _, _ = angles_at(X, np.broadcast_to(nrm, X.shape), L, cam.position)
            iv, iu = vv.astype(int), uu.astype(int)
            s0 = S[0][iv, iu]
            ok = s0 > 1e-6 * S[0].max()
            dl = np.hypot(S[1][iv, iu], S[2][iv, iu])[ok] / s0[ok]
            p = plates[reg["name"]]
            if ok.any():
                worst["eq9"] = max(worst["eq9"], float(np.abs(dl - dop_eq9_array(p["n"], p["k"], beta[ok])).max()))
            sl = (slice(y, y + h), slice(x, x + w))
            I = {a: fr[a][sl] for a in ANGLES}
            n_rej += int(sum(((I[a] >= sat) | (I[a] <= 0)).sum() for a in ANGLES))
            I = {a: v - dark for a, v in I.items()}
            dl_f, se_f = rp._dolp_se(0.5 * (I[0] + I[45] + I[90] + I[135]), I[0] - I[90], I[45] - I[135])
            q = {a: demo[a][sl] for a in ANGLES}
            dl_d, se_d = rp._dolp_se(0.5 * (q[0] + q[45] + q[90] + q[135]), q[0] - q[90], q[45] - q[135])
            tp = tc["plates"][reg["name"]]
            ideal = tp["region_dolp"]
            worst["frames"] = max(worst["frames"], abs(dl_f - ideal))
            worst["dofp"] = max(worst["dofp"], abs(dl_d - ideal))
            if tp["region_s0_dn"] >= 100:
                worst["z_frames"] = max(worst["z_frames"], abs(dl_f - ideal) / se_f)
                worst["z_dofp"] = max(worst["z_dofp"], abs(dl_d - ideal) / se_d)
            print(f"{tc['name']:7s} {reg['name']:15s} {tp['region_s0_dn']:7.0f} {ideal:8.5f} {dl_f:8.5f} {se_f:7.5f} "
                  f"{dl_d:8.5f} {se_d:7.5f} {tp['beta_mean_deg']:6.2f} {tp['beta_sd_deg']:5.2f}")
    print(f"per-pixel |DoLP_ideal - eq9(beta from the manifest geometry)| max {worst['eq9']:.2e}")
    print(f"region |DoLP - ideal| max: frames {worst['frames']:.5f}, dofp {worst['dofp']:.5f}; "
          f"largest |z| where S0 >= 100 DN: frames {worst['z_frames']:.2f}, dofp {worst['z_dofp']:.2f}; "
          f"clipped raw pixels in regions: {n_rej}")
    ok = err < 0.1 and worst["eq9"] < 1e-3
    print("check:", "OK" if ok else "FAIL")
    sys.exit(0 if ok else 1)


# ----------------------------------------------------------------------------------------
# verify-bench: the conventions this script relies on
# ----------------------------------------------------------------------------------------


def cmd_verify(args):
    variant = rp.init_mitsuba(args.variant)
    mi = rp.mi
    print(f"mitsuba {mi.__version__}, variant {variant}")
    ok = True
    # 1. Sensor rays: Mitsuba's perspective sensor built by sensor_dict vs the OpenCV
    #    model, with a principal point far off centre.
    W, H = 320, 240
    cam = Camera.from_look_at(300.0, 300.0, 200.7, 150.2, [0.5, 0.1, 0.6], [0.0, 0.05, 0.0], [0.0, 0.0, 1.0])
    b = Bench(name="verify", wavelength_nm=550.0, camera=cam, planes=[Plane("p", np.zeros(3), np.array([0, 0, 1.0]))],
              plates=[], lamps=[], lamp_specs=[], width=W, height=H)
    s = mi.load_dict(sensor_dict(b, 1))
    worst = 0.0
    for u, v in [(0, 0), (W - 1, 0), (0, H - 1), (W - 1, H - 1), (200.7, 150.2), (17.25, 201.5), (160, 120)]:
        # film position of OpenCV pixel u: u + 0.5 (pixel i covers [i, i + 1))
        ray, _ = s.sample_ray(0.0, 0.5, mi.Point2f((u + 0.5) / W, (v + 0.5) / H), mi.Point2f(0.5, 0.5))
        dm = np.array([ray.d.x[0], ray.d.y[0], ray.d.z[0]], float)
        om = np.array([ray.o.x[0], ray.o.y[0], ray.o.z[0]], float)
        dc = cam.rays(np.array(float(u)), np.array(float(v)))
        # the angle as a pixel offset at the focal length
        worst = max(worst, float(np.linalg.norm(np.cross(unit(dm), dc))) * cam.fx)
        # Mitsuba starts the ray at the near-clip plane: its origin must lie on the OpenCV ray
        off = om - cam.position
        worst = max(worst, float(np.linalg.norm(off - (off @ dc) * dc)) / float(off @ dc) * cam.fx)
    good = worst < 1e-3
    ok &= good
    print(f"sensor rays vs OpenCV pinhole (principal point off centre): max error {worst:.1e} px "
          f"{'OK' if good else 'FAIL'}")
    # 2. Stokes frame and eq. (9) at off-axis pixels: dielectric (roughconductor k = 0,
    #    n = 1.5) and copper-like plates under a point lamp.
    cam = Camera.from_look_at(220.0, 220.0, 160.4, 118.9, [0.6928, 0.0, 0.4], [0, 0, 0], [0, 0, 1.0])
    for n, k in ((1.5, 0.0), (0.4, 2.95)):
        pl = Plate(name="p", cls="p", plane="p", center=np.zeros(3), size=(1.0, 1.0), sigma=0.25, n=n, k=k,
                   reference="", x_axis=np.array([1.0, 0, 0]), y_axis=np.array([0, 1.0, 0]),
                   normal=np.array([0, 0, 1.0]))
        b = Bench(name="verify", wavelength_nm=550.0, camera=cam, planes=[Plane("p", np.zeros(3), pl.normal)],
                  plates=[pl], lamps=[], lamp_specs=[], width=W, height=H)
        L = np.array([-0.35, 0.2, 0.6])
        s0, s1, s2 = render_capture(b, L, 64)
        e9, ea, ep = 0.0, 0.0, 0.0
        for u, v in [(160, 120), (20, 220), (300, 220), (10, 120), (100, 200), (250, 150), (300, 130)]:
            lab, X, N = trace(b, np.array([float(u)]), np.array([float(v)]))
            if lab[0] == 0 or s0[v, u] <= 0:
                continue
            ti, tr, phi, beta, _, ui, ur = angles_at(X, N, L, cam.position)
            dl, al = rp.dolp_aolp(s0[v, u], s1[v, u], s2[v, u])
            e9 = max(e9, abs(dl - float(dop_eq9_array(n, k, beta[0]))))
            sdir = unit(np.cross(ui[0], ur[0]))
            a_mi = float(mitsuba_stokes_angle(b, cam.rays(np.array(float(u)), np.array(float(v))), sdir))
            ea = max(ea, abs((al - a_mi + 90) % 180 - 90))
            ep = max(ep, abs((al - float(cam.image_angle(X[0], sdir)) + 90) % 180 - 90))
        good = e9 < 2e-4 and ea < 0.05
        ok &= good
        print(f"n={n} k={k}: max |DoLP - eq9(beta at the pixel centre)| {e9:.1e}; AoLP vs the s direction in "
              f"Mitsuba's frame {ea:.3f} deg (vs its central projection: up to {ep:.2f} deg) {'OK' if good else 'FAIL'}")
    # 3. roughdielectric is not polarized in this Mitsuba (hence roughconductor with k = 0)
    sc = {"type": "scene", "integrator": {"type": "stokes", "integrator": {"type": "direct"}},
          "sensor": sensor_dict(b, 4),
          "lamp": {"type": "point", "position": [-0.35, 0.2, 0.6], "intensity": {"type": "spectrum", "value": 1.0}},
          "plate": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale([0.5, 0.5, 1]),
                    "bsdf": {"type": "roughdielectric", "distribution": "beckmann", "alpha": 0.35, "int_ior": 1.5}}}
    sc = mi.load_dict(sc)
    mi.render(sc, seed=0)
    ch = {nm: np.array(bm, dtype=np.float64) for nm, bm in sc.sensors()[0].film().bitmap().split()}
    s0, s1, s2 = (ch[c][..., 0] if ch[c].ndim == 3 else ch[c] for c in ("S0", "S1", "S2"))
    print(f"roughdielectric n=1.5 for comparison: DoLP at the centre pixel {math.hypot(s1[120, 160], s2[120, 160]) / s0[120, 160]:.4f} "
          "(unpolarized in this Mitsuba: glass plates are rendered as roughconductor with k = 0)")
    print("verify-bench:", "OK" if ok else "FAIL")
    sys.exit(0 if ok else 1)


# ----------------------------------------------------------------------------------------
# reference: what a per-pixel geometry model recovers from the files (numpy, not polarid)
# ----------------------------------------------------------------------------------------


def _load_captures(root, man, kind):
    """Per capture: lamp, dark-subtracted S0/S1/S2 per unit exposure, saturated mask."""
    dark, sat = float(man.get("dark_level", 0.0)), float(man["saturation"])
    out = []
    for c in man["capture"]:
        if kind == "dofp":
            raw = rp.read_image(os.path.join(root, c["dofp"]["file"]))
            I = demosaic_bilinear(raw - dark, c["dofp"]["pattern"])
            bad = raw >= sat
            bad = bad | np.roll(bad, 1, 0) | np.roll(bad, -1, 0)
            bad = bad | np.roll(bad, 1, 1) | np.roll(bad, -1, 1)
        else:
            fr = {int(f["angle_deg"]): rp.read_image(os.path.join(root, f["file"])) for f in c["frames"]}
            bad = np.zeros(next(iter(fr.values())).shape, bool)
            for a in fr:
                bad |= fr[a] >= sat
            I = {a: v - dark for a, v in fr.items()}
        ex = float(c.get("exposure", 1.0))
        s0 = 0.5 * (I[0] + I[45] + I[90] + I[135]) / ex
        out.append((np.array(c["source"]["position"], float), s0, (I[0] - I[90]) / ex, (I[45] - I[135]) / ex,
                    bad, ex))
    return out


def _lm_fit(model, y, se, x0, lo=(0.01, 0.0), hi=(10.0, 10.0)):
    """Levenberg-Marquardt on (model(x) - y)/se with box bounds; returns x, SE, rms."""
    def res(x):
        return (model(x) - y) / se

    def jac(x, r):
        J = np.zeros((len(r), 2))
        for q in range(2):
            h = 1e-6 * max(1.0, abs(x[q]))
            xp = x.copy()
            xp[q] = x[q] + h if x[q] + h <= hi[q] else x[q] - h
            J[:, q] = (res(xp) - r) / (xp[q] - x[q])
        return J

    x = np.array(x0, float)
    r = res(x)
    lam = 1e-3
    for _ in range(100):
        J = jac(x, r)
        A, g = J.T @ J, J.T @ r
        xn = np.clip(x - np.linalg.solve(A + lam * np.diag(np.diag(A) + 1e-12), g), lo, hi)
        rn = res(xn)
        if rn @ rn < r @ r:
            done = np.abs(xn - x).max() < 1e-10
            x, r, lam = xn, rn, lam / 3
            if done:
                break
        else:
            lam *= 5
            if lam > 1e8:
                break
    J = jac(x, r)
    cov = np.linalg.pinv(J.T @ J)
    return x, np.sqrt(np.maximum(np.diag(cov), 0.0)), float(np.sqrt(np.mean(r**2)))


def cmd_reference(args):
    """Region fits with a per-pixel forward model: the region's mean Stokes vector is
    predicted as the S0-weighted sum of every pixel's eq. (9) DoLP at its own beta, along
    the s direction of its own plane of incidence in the renders' Stokes frame (the
    measured S0 as the weights), and (n, k) fitted over the captures by least squares with
    the region DoLP's delta-method SE (x 8/3 for bilinear DoFP, cf. polarid_core::region).
    An independent yardstick for polarid's results on the same files, not polarid."""
    root = os.path.abspath(args.dir)
    with open(os.path.join(root, "truth.json")) as f:
        truth = json.load(f)
    fn = "manifest_dofp.toml" if args.dofp else "manifest.toml"
    with open(os.path.join(root, fn), "rb") as f:
        man = tomllib.load(f)
    cam = camera_from_manifest(man)
    planes = {p["name"]: (np.array(p["point"], float), unit(p["normal"])) for p in man["plane"]}
    caps = _load_captures(root, man, "dofp" if args.dofp else "frames")
    se_factor = 8.0 / 3.0 if args.dofp else 1.0
    bview = type("B", (), {"camera": cam})()
    print(f"{os.path.basename(root)} {fn}: region fits with per-pixel geometry (numpy reference)")
    prototypes = []
    for p, reg in zip(truth["plates"], man["region"]):
        x, y, w, h = reg["rect"]
        vv, uu = np.mgrid[y:y + h, x:x + w].astype(float)
        pt, nrm = planes[reg["plane"]]
        d = cam.rays(uu, vv)
        X = cam.position + (((pt - cam.position) @ nrm) / (d @ nrm))[..., None] * d
        rows = []
        for L, s0, s1, s2, bad, ex in caps:
            sl = (slice(y, y + h), slice(x, x + w))
            ok = ~bad[sl] & (s0[sl] * ex > 20.0)
            if ok.sum() < 50:
                continue
            _, _, _, beta, _, ui, ur = angles_at(X, np.broadcast_to(nrm, X.shape), L, cam.position)
            ang = np.radians(mitsuba_stokes_angle(bview, d, unit(np.cross(ui, ur))))
            dl, se = rp._dolp_se(s0[sl][ok], s1[sl][ok], s2[sl][ok])
            rows.append((beta[ok], np.clip(s0[sl][ok], 0, None), np.exp(2j * ang[ok]), dl, se * se_factor))
        yv = np.array([r[3] for r in rows])
        sev = np.array([r[4] for r in rows])

        def model(xx, rows=rows, step=1):
            return np.array([abs((r[1][::step] * dop_eq9_array(xx[0], xx[1], r[0][::step]) * r[2][::step]).sum())
                             / r[1][::step].sum() for r in rows])

        step = max(1, min(len(r[0]) for r in rows) // 100)
        best = None
        for n0 in np.linspace(0.05, 3.0, 60):
            for k0 in np.linspace(0.0, 8.0, 41):
                c = float((((model((n0, k0), step=step) - yv) / sev) ** 2).sum())
                if best is None or c < best[0]:
                    best = (c, n0, k0)
        xx, sexx, rms = _lm_fit(model, yv, sev, best[1:])
        dn, dk = xx[0] - p["n"], xx[1] - p["k"]
        tn, tk = max(0.03, 3 * sexx[0]), max(0.06, 3 * sexx[1])
        print(f"  {p['name']:15s} truth {p['n']:.3f}+{p['k']:.3f}i  fit {xx[0]:.4f}+{xx[1]:.4f}i  "
              f"se {sexx[0]:.4f}, {sexx[1]:.4f}  dn {dn:+.4f} dk {dk:+.4f}  rms {rms:.2f}  captures {len(rows)}  "
              f"{'within' if abs(dn) <= tn and abs(dk) <= tk else 'OUTSIDE'} max(0.03, 3 SE) / max(0.06, 3 SE)")
        prototypes.append((p["class"], xx[0], xx[1]))
    if args.map:
        reference_map(root, truth, man, cam, caps, prototypes, int(args.map))


def reference_map(root, truth, man, cam, caps, prototypes, B):
    """B x B blocks entirely on one plate (labels.tif): (n, k) by a grid search of eq. (9)
    at the block's S0-weighted beta over the captures where the block's mean S0 is at
    least 1 % of the range (as map's default --min-s0) and nothing saturates (DoLP SE
    from shot and read noise), then the nearest prototype (Euclidean, the region fits
    above as the trained model)."""
    import tifffile

    lab = tifffile.imread(os.path.join(root, "labels.tif")).astype(int)
    H, W = lab.shape

    def blocks(a):
        return a[:H // B * B, :W // B * B].reshape(H // B, B, W // B, B).transpose(0, 2, 1, 3).reshape(
            H // B, W // B, B * B)

    bl = blocks(lab)
    sel = (bl == bl[..., :1]).all(-1) & (bl[..., 0] > 0)
    plate_of = bl[sel][:, 0] - 1
    planes = {p["name"]: (np.array(p["point"], float), unit(p["normal"])) for p in man["plane"]}
    U, V = np.meshgrid(np.arange(W, dtype=float), np.arange(H, dtype=float))
    d = cam.rays(U, V)
    X = np.full(d.shape, np.nan)
    N = np.full(d.shape, np.nan)
    for i, p in enumerate(truth["plates"]):
        pt, nrm = planes[p["plane"]]
        m = lab == i + 1
        X[m] = cam.position + (((pt - cam.position) @ nrm) / (d[m] @ nrm))[:, None] * d[m]
        N[m] = nrm
    ng, kg = np.arange(0.01, 3.0, 0.02), np.arange(0.0, 8.0, 0.04)
    NN, KK = (a.ravel() for a in np.meshgrid(ng, kg, indexing="ij"))
    bgrid = np.radians(np.arange(0.0, 90.0, 0.05))
    table = np.stack([dop_eq9_array(NN, KK, bb) for bb in bgrid], 1).astype(np.float32)
    chi = np.zeros((len(plate_of), len(NN)), np.float32)
    nlit = np.zeros(len(plate_of), int)
    sensor = truth["sensor"]
    full = sensor["saturation_dn"] - sensor["dark_level_dn"]
    for L, s0, s1, s2, bad, ex in caps:
        beta = angles_at(X, N, L, cam.position)[3]
        S0, S1, S2, BB = (blocks(a)[sel] for a in (s0 * ex, s1 * ex, s2 * ex, beta))
        m0 = S0.sum(1)
        lit = (m0 / (B * B) >= 0.01 * full) & ~blocks(bad)[sel].any(1)
        P = np.hypot(S1.sum(1), S2.sum(1)) / np.maximum(m0, 1e-9)
        var = np.clip(S0, 0, None) / sensor["electrons_per_dn"] + 2 * sensor["read_noise_dn"] ** 2
        se = np.sqrt(var.sum(1)) / np.maximum(m0, 1e-9)
        wb = np.clip(S0, 0, None)
        bm = (wb * BB).sum(1) / np.maximum(wb.sum(1), 1e-9)
        idx = np.clip(np.rint(np.degrees(bm) / 0.05).astype(int), 0, len(bgrid) - 1)
        for j in np.nonzero(lit)[0]:
            chi[j] += ((table[:, idx[j]] - P[j]) / se[j]) ** 2
        nlit += lit
    best = chi.argmin(1)
    nf, kf = NN[best], KK[best]
    dist = np.stack([np.hypot(nf - n, kf - k) for _, n, k in prototypes], 1)
    pred = np.array([prototypes[i][0] for i in dist.argmin(1)])
    want = np.array([truth["plates"][i]["class"] for i in plate_of])
    ok = nlit >= 3
    print(f"  map emulation, {B}x{B} blocks: {len(ok)} plate blocks, {100 * ok.mean():.1f} % classified "
          f"(>= 3 lit captures), {100 * (pred[ok] == want[ok]).mean():.2f} % of those right")
    for i, p in enumerate(truth["plates"]):
        s = (plate_of == i) & ok
        print(f"    {p['name']:15s} {int((plate_of == i).sum()):4d} blocks, {int(s.sum()):4d} classified, "
              f"{100 * (pred[s] == want[s]).mean():6.2f} % right")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("render", help="render a bench TOML at one wavelength into a capture set directory")
    r.add_argument("bench")
    r.add_argument("--wavelength", type=float, required=True, help="band key of the plates' nk tables, nm")
    r.add_argument("-o", "--output", required=True)
    r.add_argument("--variant", default="auto")
    r.add_argument("--force", action="store_true")
    r.add_argument("--quiet", action="store_true")
    c = sub.add_parser("check", help="re-measure a rendered bench set (geometry from its manifest)")
    c.add_argument("dir")
    v = sub.add_parser("verify-bench", help="sensor, Stokes-frame and eq. (9) checks of the bench renderer")
    v.add_argument("--variant", default="auto")
    f = sub.add_parser("reference", help="numpy per-pixel-geometry region fits of a set (a yardstick)")
    f.add_argument("dir")
    f.add_argument("--dofp", action="store_true", help="use manifest_dofp.toml instead of manifest.toml")
    f.add_argument("--map", metavar="B", help="also emulate a B x B binned map classified with the region fits")
    args = ap.parse_args()
    {"render": cmd_render, "check": cmd_check, "verify-bench": cmd_verify, "reference": cmd_reference}[args.cmd](args)


if __name__ == "__main__":
    main()
