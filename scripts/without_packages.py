#!/usr/bin/python3
# SPDX-License-Identifier: Apache-2.0
"""Runs a command as on a machine without the named Debian packages.

In a private mount namespace, every file and symlink the packages installed (headers,
pkg-config and CMake files, libraries, documentation) is whited out by an overlay, so that it
is absent, not merely empty. Needs root and unshare(2); where the namespace or an overlay cannot
be made (e.g. a container without CAP_SYS_ADMIN), it says so and runs the command with the
packages installed.

usage: scripts/without_packages.py PKG[,PKG...] COMMAND [ARGS...]
"""
import os
import subprocess
import sys
import tempfile

INSIDE = "THINSLAB_WITHOUT_PACKAGES_INSIDE"


def run_as_is(command, why):
    print(f"thinslab: {why}: running with the packages' files in place", file=sys.stderr, flush=True)
    os.execvp(command[0], command)


def installed_paths(package):
    listing = subprocess.run(["dpkg", "-L", package], capture_output=True, text=True)
    if listing.returncode != 0:
        return []  # Not installed: nothing to hide.
    return [p for p in listing.stdout.splitlines() if os.path.islink(p) or os.path.isfile(p)]


def main():
    packages, command = sys.argv[1].split(","), sys.argv[2:]
    if os.environ.get(INSIDE) != "1":
        try:
            probe = subprocess.run(["unshare", "--mount", "--propagation", "private", "true"], capture_output=True)
            possible = os.geteuid() == 0 and probe.returncode == 0
        except OSError:  # No unshare(1).
            possible = False
        if not possible:
            run_as_is(command, "no private mount namespace here (root and unshare(2) needed)")
        os.execvpe("unshare", ["unshare", "--mount", "--propagation", "private", sys.executable,
                               os.path.abspath(__file__), *sys.argv[1:]], {**os.environ, INSIDE: "1"})

    hidden = sorted({p for package in packages for p in installed_paths(package)})
    # One overlay per top folder: the folders holding hidden entries, each merged into an
    # ancestor that is itself one of them (an overlay whites out entries at any depth below it;
    # overlays stacked on overlays are limited in depth).
    folders = sorted({os.path.dirname(p) for p in hidden}, key=len)
    tops = []
    for folder in folders:
        if not any(folder == t or folder.startswith(t + "/") for t in tops):
            tops.append(folder)
    scratch = tempfile.mkdtemp(prefix="thinslab-hide-")
    mounted = subprocess.run(["mount", "-t", "tmpfs", "thinslab-hide", scratch], capture_output=True, text=True)
    if mounted.returncode != 0:
        run_as_is(command, f"cannot mount a tmpfs ({mounted.stderr.strip()})")
    for index, top in enumerate(tops):
        upper, work = os.path.join(scratch, str(index), "upper"), os.path.join(scratch, str(index), "work")
        os.makedirs(work)
        for path in hidden:
            if path.startswith(top + "/"):
                whiteout = os.path.join(upper, os.path.relpath(path, top))
                os.makedirs(os.path.dirname(whiteout), exist_ok=True)
                os.mknod(whiteout, 0o600 | 0o020000, os.makedev(0, 0))  # Character device 0/0.
        mounted = subprocess.run(["mount", "-t", "overlay", "thinslab-hide", "-o",
                                  f"lowerdir={top},upperdir={upper},workdir={work}", top], capture_output=True, text=True)
        if mounted.returncode != 0:  # The overlays mounted before this one stay.
            run_as_is(command, f"cannot overlay {top} ({mounted.stderr.strip()}): its files stay")
    print(f"thinslab: {len(hidden)} files of {' '.join(packages)} hidden (overlays on {' '.join(tops)})",
          file=sys.stderr, flush=True)
    os.execvp(command[0], command)


if __name__ == "__main__":
    main()
