# SPDX-License-Identifier: Apache-2.0
"""The Python bindings (issue #25): reading captures and outputs, fits with the CLI's options and
messages, the vectorised optics models, the tutorial."""
import math
import os
import runpy
import subprocess

import numpy as np
import pytest

import thinslab

BINARY_DIR = os.environ.get("THINSLAB_BINARY_DIR", "")
SOURCE_DIR = os.environ.get("THINSLAB_SOURCE_DIR", "")
CLI = os.path.join(BINARY_DIR, "app", "thinslab")
SMALL_SHADOW = dict(camera_width_px=200, camera_height_px=150, photons=20000, frames=2)


@pytest.fixture(scope="module")
def shadow_capture(tmp_path_factory):
    capture = str(tmp_path_factory.mktemp("shadow") / "capture")
    thinslab.sim("shadow-maps", capture, **SMALL_SHADOW)
    return capture


def test_read_capture_and_frame(shadow_capture):
    info = thinslab.read_capture(shadow_capture)
    assert info["kind"] == "shadow_map"
    camera = info["cameras"][0]
    kinds = {f["kind"] for f in info["frames"]}
    assert {"shadow", "reference", "dark"} <= kinds
    frame = thinslab.read_frame(shadow_capture, info["frames"][0]["index"])
    assert frame.dtype == np.float32
    assert frame.shape == (camera["height_px"], camera["width_px"])
    assert 0 < frame.max() <= camera["saturation_dn"]
    with pytest.raises(IndexError):
        thinslab.read_frame(shadow_capture, 10**6)
    with pytest.raises(ValueError, match="session.json"):
        thinslab.read_capture(os.path.join(shadow_capture, "no_such_capture"))


def test_fit_tau_equals_the_cli(shadow_capture, tmp_path):
    fit = thinslab.fit_tau(shadow_capture, out=str(tmp_path / "py"), albedo=0.3, split_half_check=False)
    assert fit.summary["result"] == "success"
    tau = fit.maps["tau"]
    assert tau.shape == tuple(fit.summary["grid"][::-1])
    assert set(fit.maps) >= {"tau", "tau_eq7", "status", "sigma_tau"}
    assert fit.attributes["options_digest"].startswith("fnv1a64:")
    # The same fit through the CLI binary: the same map, bit for bit.
    subprocess.run([CLI, "fit", "tau", shadow_capture, "--out", str(tmp_path / "cli"), "--albedo", "0.3",
                    "--split-half-check", "false"], check=True, capture_output=True)
    cli_maps, _ = thinslab.read_exr(str(tmp_path / "cli" / "tau.exr"))
    np.testing.assert_array_equal(cli_maps["tau"], tau)
    np.testing.assert_array_equal(cli_maps["sigma_tau"], fit.maps["sigma_tau"])
    again = thinslab.read_fit(str(tmp_path / "py"))
    assert again.summary == fit.summary


def test_options_errors_are_the_cli_messages(shadow_capture, tmp_path):
    with pytest.raises(thinslab.ThinslabError, match=r"TauFitOptions::layer_albedo = 2\. Violated constraint"):
        thinslab.fit_tau(shadow_capture, out=str(tmp_path / "bad"), albedo=2)
    with pytest.raises(thinslab.ThinslabError, match="unknown option --no-such-option"):
        thinslab.fit_tau(shadow_capture, out=str(tmp_path / "bad2"), no_such_option=1)
    assert not os.path.exists(tmp_path / "bad")


def test_fit_phase_and_predict(tmp_path):
    capture = str(tmp_path / "laser")
    thinslab.sim("laser", capture, camera_width_px=200, camera_height_px=150, photons=20000, g=0.6)
    fit = thinslab.fit_phase(capture)
    assert fit.summary["result"] == "success"
    assert abs(fit.summary["g"] - 0.6) < 0.15
    assert len(fit.rings["theta_deg"]) >= 5
    prediction = thinslab.predict(capture)
    assert prediction


def test_hg_phase_integrates_to_one_and_broadcasts():
    mu = np.linspace(-1, 1, 20001)
    for g in (-0.5, 0.0, 0.3, 0.8):
        integral = 2 * math.pi * np.trapz(thinslab.hg_phase(mu, g), mu)
        assert abs(integral - 1) < 1e-3
    grid = thinslab.hg_phase(mu[:, None][:5], np.array([0.1, 0.5, 0.9]))
    assert grid.shape == (5, 3)
    assert grid[2, 1] == pytest.approx(thinslab.hg_phase(mu[2], 0.5))


def test_gu_layer_models_agree_with_each_other():
    mu = np.linspace(0.2, 1.0, 9)
    lobe = thinslab.gu_laser_lobe(mu, 0.7, 0.4)
    np.testing.assert_allclose(lobe, thinslab.gu_scattered_radiance(0.4, mu, 1.0, 0.7) * mu**4, rtol=1e-12)
    assert thinslab.gu_direct_transmittance(0.5) == pytest.approx(math.exp(-0.5))


def test_frisvad_slab_is_thin_limit_of_single_scattering():
    # Transmitted single scattering at normal incidence and exit grows as tau1 e^-tau1 for a thin slab.
    small = thinslab.frisvad_transmitted_bsdf(1.0, 1.0, 1.0, 1e-4, 1.0, 0.0)
    assert small == pytest.approx(1e-4 / (4 * math.pi), rel=1e-3)
    assert thinslab.frisvad_direct_transmittance(0.5, 0.2) == pytest.approx(math.exp(-0.4))


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def test_walter_bsdf_vectorised_and_checked():
    wi = unit([0.3, 0.0, 1.0])
    wo = unit(np.stack([np.linspace(-0.5, 0.5, 7), np.zeros(7), -np.ones(7)], axis=1))
    ggx = thinslab.walter_bsdf(wi, wo, 0.2, 1.5, "ggx")
    beckmann = thinslab.walter_bsdf(wi, wo, 0.2, 1.5, "beckmann")
    assert ggx.shape == (7,) and np.all(ggx > 0) and np.all(beckmann > 0)
    assert not np.allclose(ggx, beckmann)
    for k in range(7):
        assert thinslab.walter_bsdf(wi, wo[k], 0.2, 1.5, "ggx") == pytest.approx(ggx[k])
    with pytest.raises(ValueError, match="distribution"):
        thinslab.walter_bsdf(wi, wo, 0.2, 1.5, "phong")
    with pytest.raises(ValueError, match=r"\(\.\.\., 3\)"):
        thinslab.walter_bsdf(np.zeros((4, 2)), wo, 0.2)


def test_dai_btdf_weights_the_faces():
    wi = unit([0.2, 0.1, 1.0])
    wo = unit(np.stack([np.linspace(-0.4, 0.4, 5), np.zeros(5), -np.ones(5)], axis=1))
    top = thinslab.dai_btdf(wi, wo, 0.3, top_weight=1.0)
    bottom = thinslab.dai_btdf(wi, wo, 0.3, top_weight=0.0)
    half = thinslab.dai_btdf(wi, wo, 0.3, top_weight=0.5)
    assert np.all(top > 0) and np.all(bottom > 0)
    np.testing.assert_allclose(half, np.sqrt(top * bottom), rtol=1e-10)  # Dai Eq. 11.
    assert thinslab.dai_btdf(wi, unit([0, 0, 1]), 0.3) == 0  # Not transmitted.


def test_tutorial_runs(tmp_path, monkeypatch):
    pytest.importorskip("matplotlib")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.chdir(tmp_path)
    runpy.run_path(os.path.join(SOURCE_DIR, "python", "examples", "tutorial.py"), run_name="__main__")
    assert (tmp_path / "tutorial_tau.png").stat().st_size > 10000


def test_progress_reports_and_cancels(shadow_capture, tmp_path):
    updates = []
    fit = thinslab.fit_tau(shadow_capture, out=str(tmp_path / "reported"), split_half_check=False,
                           progress=lambda u: updates.append(u) or True)
    assert fit.summary["result"] == "success"
    assert updates and all(u["stage"].startswith("fit tau") for u in updates)
    assert updates[-1]["done"] == updates[-1]["total"] > 0
    with pytest.raises(thinslab.ThinslabError, match="cancelled"):
        thinslab.fit_tau(shadow_capture, out=str(tmp_path / "cancelled"), progress=lambda u: False)
    assert not os.path.exists(tmp_path / "cancelled")

    def failing(update):
        raise KeyError("from the callback")
    with pytest.raises(KeyError, match="from the callback"):
        thinslab.fit_tau(shadow_capture, out=str(tmp_path / "raised"), progress=failing)
    assert not os.path.exists(tmp_path / "raised")


def test_progress_of_simulations_and_calibrations(shadow_capture, tmp_path):
    """Issue #26 item 4: the dot-scan simulation and the HDR merge report progress too."""
    updates = []
    thinslab.run("sim", "dot-scan", str(tmp_path / "dots"), grid_nx=4, grid_ny=4, photons_k=2, camera_width_px=120,
                 camera_height_px=90, table_bins=16, progress=lambda u: updates.append(u) or True)
    frames = [u for u in updates if u["stage"] == "sim dot-scan: frames rendered"]
    assert frames and frames[-1]["done"] == frames[-1]["total"] >= 16
    with pytest.raises(thinslab.ThinslabError, match="cancelled"):
        thinslab.run("sim", "dot-scan", str(tmp_path / "dots_cancelled"), grid_nx=4, grid_ny=4, photons_k=2,
                     camera_width_px=120, camera_height_px=90, table_bins=16, progress=lambda u: u["done"] < 3)
    updates.clear()
    thinslab.sim("shadow-maps", str(tmp_path / "shadow"), progress=lambda u: updates.append(u) or True, **SMALL_SHADOW)
    assert updates[-1]["stage"] == "sim shadow-maps: frames rendered"
    assert updates[-1]["done"] == updates[-1]["total"] >= 4
    with pytest.raises(thinslab.ThinslabError, match="cancelled"):
        thinslab.sim("shadow-maps", str(tmp_path / "shadow_cancelled"), progress=lambda u: u["done"] < 2,
                     **SMALL_SHADOW)
    updates.clear()
    thinslab.run("calib", "hdr", shadow_capture, out=str(tmp_path / "hdr"), progress=lambda u: updates.append(u) or True)
    assert updates[-1]["stage"] == "calib hdr: groups merged"
    assert updates[-1]["done"] == updates[-1]["total"] >= 2


def test_outputs_read_with_openimageio_and_opencv(shadow_capture, tmp_path):
    """Issue #26 item 1: tau.exr as a user's program reads it (OpenImageIO lists layers and the
    integer status; cv::imread returns the primary map), and read_exr's typed attributes."""
    import OpenImageIO  # Debian python3-openimageio, python3-opencv (scripts/install_deps.sh).
    os.environ["OPENCV_IO_ENABLE_OPENEXR"] = "1"  # OpenCV's own opt-in, read when cv2 loads.
    import cv2

    fit = thinslab.fit_tau(shadow_capture, out=str(tmp_path / "fit"), split_half_check=False)
    path = str(tmp_path / "fit" / "tau.exr")
    image = OpenImageIO.ImageInput.open(path)
    assert image is not None, OpenImageIO.geterror()
    spec = image.spec()
    names = list(spec.channelnames)
    assert {"Y", "tau.Y", "tau_eq7.Y", "sigma_tau.Y", "status.Y"} <= set(names)
    formats = [str(f) for f in spec.channelformats] if spec.channelformats else [str(spec.format)] * len(names)
    assert formats[names.index("status.Y")] == "uint"
    assert formats[names.index("tau.Y")] == "float"
    assert spec.getattribute("options_digest") == fit.attributes["options_digest"]
    assert spec.getattribute("thinslab_command") == "fit tau"
    pixels = image.read_image("float")
    status_channel = names.index("status.Y")  # Integers: read as such (OIIO normalises them to float).
    status = image.read_image(0, 0, status_channel, status_channel + 1, "uint")
    image.close()
    np.testing.assert_array_equal(pixels[:, :, names.index("tau.Y")], fit.maps["tau"])
    assert status.dtype == np.uint32 and status.max() > 0
    np.testing.assert_array_equal(status[:, :, 0], fit.maps["status"])

    seen = cv2.imread(path, cv2.IMREAD_UNCHANGED)
    assert seen is not None and seen.dtype == np.float32
    np.testing.assert_array_equal(seen, fit.maps["tau"])

    _, attributes = thinslab.read_exr(path)
    assert attributes["pixel_pitch_m"] == fit.summary["resolution"]["map_pitch_m"]
    assert len(attributes["worldToCamera"]) == 16
