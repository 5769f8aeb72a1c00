"""The package as built and as installed: generated from this tessel.h, and
`make install` puts it where it finds the installed library by itself."""
import glob
import hashlib
import os
import subprocess
import sys

import pytest

import tessel


def _env(name):
    v = os.environ.get(name)
    if not v:
        pytest.skip("%s not set (run through ctest)" % name)
    return v


def test_generated_from_this_header():
    src = _env("TESSEL_SOURCE_DIR")
    with open(os.path.join(src, "include", "tessel.h"), "rb") as fh:
        assert hashlib.sha256(fh.read()).hexdigest() == tessel._lib._abi.HEADER_SHA256


def test_tessel_library_variable(tmp_path):
    env = dict(os.environ, TESSEL_LIBRARY=str(tmp_path / "missing.so"))
    r = subprocess.run([sys.executable, "-c", "import tessel"], env=env,
                       stderr=subprocess.PIPE, text=True)
    assert r.returncode != 0 and "missing.so" in r.stderr and "TESSEL_LIBRARY" in r.stderr
    env["TESSEL_LIBRARY"] = tessel.library_path
    out = subprocess.run([sys.executable, "-c", "import tessel; print(tessel.library_path)"],
                         env=env, check=True, stdout=subprocess.PIPE, text=True).stdout
    assert out.strip() == tessel.library_path


def test_installed_package_finds_the_installed_library(tmp_path):
    build = _env("TESSEL_BUILD_DIR")
    prefix = tmp_path / "prefix"
    subprocess.run(["cmake", "--install", build, "--prefix", str(prefix)], check=True,
                   stdout=subprocess.DEVNULL)
    inits = glob.glob(str(prefix / "**" / "tessel" / "__init__.py"), recursive=True)
    assert len(inits) == 1, inits
    site = os.path.dirname(os.path.dirname(inits[0]))
    # Moved elsewhere: the path to the library is relative.
    moved = tmp_path / "moved"
    os.rename(prefix, moved)
    site = site.replace(str(prefix), str(moved))
    env = {k: v for k, v in os.environ.items() if k not in ("TESSEL_LIBRARY", "LD_LIBRARY_PATH")}
    env["PYTHONPATH"] = site
    code = ("import tessel, numpy as np; print(tessel.__version__); print(tessel.library_path);"
            "m = tessel.reconstruct(np.random.default_rng(1).normal(size=(500, 3)));"
            "print(len(m.faces) > 0)")
    out = subprocess.run([sys.executable, "-c", code], env=env, cwd=str(tmp_path), check=True,
                         stdout=subprocess.PIPE, text=True).stdout.split("\n")
    assert out[0] == tessel.__version__
    assert out[1].startswith(str(moved)) and "libtessel.so" in out[1]
    assert out[2] == "True"
