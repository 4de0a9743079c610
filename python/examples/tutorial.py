# SPDX-License-Identifier: Apache-2.0
# The Python tutorial of docs/python.md, runnable as a script (python/tests runs it):
# simulate a shadow-map capture, fit tau, compare with the ground truth, plot the map.
import os

import matplotlib.pyplot as plt
import numpy as np

import thinslab

# 1. A small simulated capture of dusty glass (the bundled demo pattern, 200 x 150 camera).
capture = "tutorial_capture"
if not os.path.exists(capture):
    thinslab.sim("shadow-maps", capture, camera_width_px=200, camera_height_px=150, photons=20000, frames=2)
info = thinslab.read_capture(capture)
print(info["kind"], len(info["frames"]), "frames from", info["cameras"][0]["id"])

# 2. Fit the optical thickness map with the CLI's options as keyword arguments.
fit = thinslab.fit_tau(capture, albedo=0.3, out=os.path.join(capture, "fit", "tau_tutorial"))
tau, status, sigma = fit.maps["tau"], fit.maps["status"], fit.maps["sigma_tau"]
ok = status == 0
print("fitted %d of %d pixels, median sigma_tau %.4f" % (ok.sum(), ok.size, np.median(sigma[ok])))

# 3. The simulated capture carries its ground truth: how many pixels lie within 2 sigma of it?
truth, _ = thinslab.read_exr(os.path.join(capture, "ground_truth", "tau.exr"))
error = tau - truth["tau"]
print("within 2 sigma: %.2f" % np.mean(np.abs(error[ok]) <= 2 * sigma[ok]))

# 4. Plot the map, its error bars and the error, in mm on the sample.
pitch_mm = fit.summary["resolution"]["map_pitch_m"] * 1e3
extent = [0, tau.shape[1] * pitch_mm, tau.shape[0] * pitch_mm, 0]
fig, axes = plt.subplots(1, 3, figsize=(12, 3.6))
for ax, image, title, cmap, limits in [
        (axes[0], np.where(ok, tau, np.nan), "tau", "viridis", (0, np.nanpercentile(tau, 99.5))),
        (axes[1], np.where(ok, sigma, np.nan), "sigma_tau", "magma", (0, np.nanpercentile(sigma[ok], 99))),
        (axes[2], np.where(ok, error, np.nan), "tau - truth", "RdBu_r", (-0.1, 0.1))]:
    shown = ax.imshow(image, cmap=cmap, vmin=limits[0], vmax=limits[1], extent=extent)
    ax.set_title(title)
    ax.set_xlabel("x [mm]")
    fig.colorbar(shown, ax=ax, shrink=0.8)
axes[0].set_ylabel("y [mm]")
fig.tight_layout()
fig.savefig("tutorial_tau.png", dpi=100)
print("wrote tutorial_tau.png")
