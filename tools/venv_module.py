"""Run a tools/ script inside a virtual environment that has one PyPI module.

Shared by the checks that read our files with an independent library (meshlab_check.py with
pymeshlab, gltf_check.py with pygltflib): `ensure(module, venv, tag, what)` returns when
`module` imports; otherwise it creates target/<venv> (once), installs `module` into it, and
re-runs the calling script there. If PyPI cannot be reached it prints why and exits 3, which
the callers and CI read as "the check did not run", not as a failure of our files.
"""
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def ensure(module, venv, tag, what):
    """Return if `module` imports; else re-exec the script in target/`venv` with it."""
    try:
        __import__(module)
        return
    except ImportError:
        pass
    path = os.path.join(ROOT, "target", venv)
    py = os.path.join(path, "bin", "python")
    try:
        if not os.path.exists(py):
            subprocess.check_call([sys.executable, "-m", "venv", path])
        subprocess.check_call([py, "-c", f"import {module}"], stderr=subprocess.DEVNULL)
    except subprocess.CalledProcessError:
        try:
            subprocess.check_call([py, "-m", "pip", "install", "-q", module])
        except (subprocess.CalledProcessError, OSError) as e:
            # Not a failure of our files: say so and let the caller decide (exit 3).
            print(f"{tag}: cannot install {module} ({e}); {what} not run")
            sys.exit(3)
    os.execv(py, [py] + sys.argv)
