# SPDX-License-Identifier: Apache-2.0
"""thinslab from Python (issue #25).

Captures and every fit output as numpy arrays with their metadata; each fit, calibration,
simulation and ``predict`` run in-process with exactly the CLI's options (keyword arguments named
as the CLI's ``--options`` with ``_`` for ``-``), defaults and error messages (raised as
:class:`ThinslabError`); the optics models evaluated on numpy arrays.

    import thinslab
    thinslab.sim("shadow-maps", "cap", camera_width_px=200, camera_height_px=150)
    fit = thinslab.fit_tau("cap", albedo=0.3)
    fit.maps["tau"], fit.summary["pixels"]
"""
import json
import os
import warnings

# An installed package (<prefix>/lib/python3.X/dist-packages/thinslab) finds the bundled data of
# its install (<prefix>/share/thinslab/data) unless THINSLAB_DATA_DIR says otherwise.
_installed_data = os.path.join(os.path.dirname(os.path.abspath(__file__)), *[os.pardir] * 4, "share", "thinslab", "data")
if os.path.isdir(_installed_data):
    os.environ.setdefault("THINSLAB_DATA_DIR", os.path.normpath(_installed_data))

from . import _thinslab  # noqa: E402
from ._thinslab import (dai_btdf, frisvad_direct_transmittance, frisvad_reflected_bsdf,  # noqa: F401
                        frisvad_transmitted_bsdf, gu_direct_transmittance, gu_laser_lobe, gu_scattered_radiance,
                        hg_phase, read_capture, read_exr, read_frame, walter_bsdf)

__version__ = _thinslab.__version__
git_hash = _thinslab.git_hash


class ThinslabError(RuntimeError):
    """A thinslab command failed; the message is the CLI's, naming the file, field or option."""


def _option_args(options):
    args = []
    for name, value in options.items():
        if value is None:
            continue
        if isinstance(value, bool):
            value = "true" if value else "false"
        elif isinstance(value, (list, tuple)):
            value = ",".join(str(v) for v in value)
        args += ["--" + name.replace("_", "-"), str(value)]
    return args


def run(*args, progress=None, _stacklevel=2, **options):
    """Runs ``thinslab ARGS --OPTIONS`` in-process; returns its standard output.

    ``progress``, if given, is called with a dict (stage, done, total, elapsed_s, eta_s) as long
    operations advance (tau's scattered-light iterations, the dot frames and point fits of fit
    dmf); returning False cancels the command, which then raises ThinslabError ("... cancelled")
    and writes nothing. Warnings the command prints are issued as Python warnings; a failure
    raises ThinslabError.
    """
    command = [str(a) for a in args] + _option_args(options)
    code, out, err = _thinslab.run_command(command, progress)
    errors = []
    for line in err.splitlines():
        if line.startswith("warning: "):
            warnings.warn(line[len("warning: "):], stacklevel=_stacklevel + 1)
        elif line.strip():
            errors.append(line[len("error: "):] if line.startswith("error: ") else line)
    if code != 0:
        raise ThinslabError("\n".join(errors) or "thinslab %s exited with %d" % (" ".join(command), code))
    return out


class FitResult:
    """A fit's output folder: ``summary`` (summary.json), ``maps`` and ``attributes`` (the EXR map
    of ``fit tau`` / ``fit dmf``; empty for ``fit phase``), ``rings`` (``fit phase``: rings.csv as
    a dict of columns), ``log`` (what the command printed)."""

    def __init__(self, out_dir, log=""):
        self.out_dir = out_dir
        self.log = log
        self.summary = read_json(os.path.join(out_dir, "summary.json"))
        self.maps, self.attributes = {}, {}
        for name in ("tau.exr", "maps.exr"):
            path = os.path.join(out_dir, name)
            if os.path.exists(path):
                self.maps, self.attributes = read_exr(path)
        rings = os.path.join(out_dir, "rings.csv")
        self.rings = read_csv(rings) if os.path.exists(rings) else None

    def __repr__(self):
        return "FitResult(%r, result=%r)" % (self.out_dir, self.summary.get("result"))


def read_json(path):
    with open(path, encoding="utf-8") as f:
        return json.load(f)


def read_csv(path):
    """A thinslab CSV (``#`` comment lines, a header row, numbers) as {column: list of floats}."""
    import csv
    with open(path, encoding="utf-8") as f:
        rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
    header, body = rows[0], rows[1:]
    columns = {name: [] for name in header}
    for r in body:
        for name, value in zip(header, r):
            try:
                columns[name].append(float(value))
            except ValueError:
                columns[name].append(value)
    return columns


def read_fit(out_dir):
    """Reads a ``fit tau``, ``fit phase`` or ``fit dmf`` output folder."""
    return FitResult(out_dir)


def _fit(kind, capture, out, progress, options):
    out_dir = out or os.path.join(capture, "fit", kind)
    log = run("fit", kind, capture, out=out, progress=progress, _stacklevel=4, **options)
    return FitResult(out_dir, log)


def fit_tau(capture, out=None, progress=None, **options):
    """``thinslab fit tau``: optical thickness map (Gu et al. 2007, Eqs. 5-7). Returns a FitResult."""
    return _fit("tau", capture, out, progress, options)


def fit_phase(capture, out=None, progress=None, **options):
    """``thinslab fit phase``: Henyey-Greenstein g from the laser lobe (Gu et al. 2007, Eq. 8)."""
    return _fit("phase", capture, out, progress, options)


def fit_dmf(capture, out=None, progress=None, **options):
    """``thinslab fit dmf``: dual-microfacet maps from a dot scan (Dai et al. 2009)."""
    return _fit("dmf", capture, out, progress, options)


def predict(capture, fit=None, out=None, **options):
    """``thinslab predict``: what a fit predicts for a capture; returns summary.json as a dict."""
    out_dir = out or os.path.join(capture, "fit", "predict")
    run("predict", capture, fit=fit, out=out, _stacklevel=3, **options)
    return read_json(os.path.join(out_dir, "summary.json"))


def calib(kind, capture, **options):
    """``thinslab calib KIND CAPTURE``: response, hdr, flat, pose, dots, gamma. Returns the log."""
    return run("calib", kind, capture, _stacklevel=3, **options)


def sim(kind, out, **options):
    """``thinslab sim KIND OUT``: shadow-maps, laser or dot-scan simulated captures."""
    return run("sim", kind, out, _stacklevel=3, **options)
