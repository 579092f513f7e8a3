"""From polarization frames to a material map, in a dozen numpy lines (notebook-style).

Run from anywhere (headless; writes a PNG):

    python python/examples/frames_to_map.py [-o material_map.png]

1. simulate captures of six plates of known materials (or load your own frames: any
   (N, H, W) array per source position works, e.g. ``cv2.imread(f, cv2.IMREAD_UNCHANGED)``
   for each polarizer angle);
2. Stokes images per capture, smoothed over 3x3 pixels, and the DoLP;
3. fit (n, k) per pixel over the source positions (``fit_nk`` on an (H, W, C) stack);
4. classify every pixel against a small model (a list of (class, n, k) prototypes);
5. plot DoLP, n, k and the material map with matplotlib.
"""

# %% imports
import argparse

import matplotlib

matplotlib.use("Agg")  # headless
import matplotlib.pyplot as plt
import numpy as np

import polarid

ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
ap.add_argument("-o", "--output", default="material_map.png")
args = ap.parse_args()

# %% 1. simulated captures: six plates, the source moved over ten zenith angles
materials = {  # (n, k) near 650 nm
    "aluminium": (1.49, 7.82),
    "gold": (0.17, 3.48),
    "copper": (0.24, 3.42),
    "steel": (2.87, 3.35),
    "glass": (1.51, 0.0),
    "plastic": (1.59, 0.0),
}
plates = [(n, k, 0.15) for n, k in materials.values()]
theta_i = np.linspace(20.0, 75.0, 10)
sim = polarid.simulate(plates, theta_i, theta_r_deg=50.0, tile=24, gap=6, seed=1)
frames = sim["frames"]  # (C, A, H, W) uint16: C source positions, A polarizer angles
print(f"{frames.shape[0]} captures of {frames.shape[1]} frames, {frames.shape[2]}x{frames.shape[3]} px")

# %% 2. Stokes -> DoLP per capture (3x3 box mean of the Stokes images first: the DoLP
# of a mean Stokes vector is unbiased, the mean of noisy DoLP values is not)
def box3(s):
    p = np.pad(s, ((0, 0), (1, 1), (1, 1)), mode="edge")
    return sum(p[:, i:i + s.shape[1], j:j + s.shape[2]] for i in range(3) for j in range(3)) / 9


stokes = [box3(polarid.stokes(f, sim["angles_deg"]).astype(np.float64)) for f in frames]
dolp = np.stack([polarid.dolp(s) for s in stokes], axis=-1)  # (H, W, C)
lit = (np.stack([s[0] for s in stokes], axis=-1) > 50).all(axis=-1)  # S0 > 50 DN everywhere

# %% 3. per-pixel (n, k) fit over the C source positions (GIL released, all cores)
y = np.where(lit[..., None], dolp, np.nan)  # unlit pixels -> status invalid_input
fit = polarid.fit_nk(y, sim["beta_deg"])
ok = fit["status_code"] == fit["status_names"].index("ok")  # codes, no per-pixel strings
print(f"fitted {ok.sum()} of {lit.sum()} lit pixels with status ok")

# %% 4. classify against a small model
model = [(name, n, k) for name, (n, k) in materials.items()]
cls = polarid.classify(fit["n"], fit["k"], model, fit_status=fit["status_code"])
names = list(materials)
label = np.full(ok.shape, -1)
for i, name in enumerate(names):  # predicted_code indexes cls["class_names"]
    label[cls["predicted_code"] == cls["class_names"].index(name)] = i
for p, ((x, yy, w, h), name) in enumerate(zip(sim["rects"], names)):
    region = label[yy + 2:yy + h - 2, x + 2:x + w - 2]
    share = np.mean(region == p)
    print(f"  plate {p} ({name}): {100 * share:.0f}% of its pixels classified {name}")

# %% 5. plot
fig, ax = plt.subplots(4, 1, figsize=(9, 8), constrained_layout=True)
im = ax[0].imshow(dolp[..., 4], vmin=0, vmax=1, cmap="viridis")
ax[0].set_title(f"DoLP, source at {theta_i[4]:.0f}°")
fig.colorbar(im, ax=ax[0])
for a, key, vmax in ((ax[1], "n", 3.5), (ax[2], "k", 8.0)):
    im = a.imshow(np.where(ok, fit[key], np.nan), vmin=0, vmax=vmax, cmap="magma")
    a.set_title(f"fitted {key}")
    fig.colorbar(im, ax=a)
cmap = plt.get_cmap("tab10", len(names))
im = ax[3].imshow(np.ma.masked_less(label, 0), cmap=cmap, vmin=-0.5, vmax=len(names) - 0.5)
ax[3].set_title("material map (unknown / unlit: blank)")
cb = fig.colorbar(im, ax=ax[3], ticks=range(len(names)))
cb.ax.set_yticklabels(names)
for a in ax:
    a.set_xticks([])
    a.set_yticks([])
fig.savefig(args.output, dpi=120)
print(f"wrote {args.output}")
