"""Chromium for the browser tests: the installed binary, or Debian's ``chromium`` package
installed with apt-get where the test runs as root; else None (the caller skips and says why)."""

from __future__ import annotations

import os
import shutil
import subprocess

#: why a browser test skips where this returns None
NO_CHROMIUM = "no Chromium, and it cannot be installed here (needs root and apt-get)"
#: software WebGL (SwiftShader): no GPU needed
SOFTWARE_GL = ["--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader"]


def find_or_install_chromium() -> str | None:
    """The Chromium binary, installed with apt-get if missing and possible; else None."""
    for name in ("chromium", "chromium-browser", "google-chrome"):
        path = shutil.which(name)
        if path:
            return path
    if os.geteuid() != 0 or shutil.which("apt-get") is None:
        return None
    env = {**os.environ, "DEBIAN_FRONTEND": "noninteractive"}
    try:
        subprocess.run(["apt-get", "update", "-qq"], check=True, env=env, capture_output=True, timeout=600)
        subprocess.run(["apt-get", "install", "-y", "-qq", "chromium"], check=True, env=env, capture_output=True,
                       timeout=1200)
    except (subprocess.SubprocessError, OSError) as exc:
        print(f"installing chromium failed: {exc}")
        return None
    return shutil.which("chromium")
