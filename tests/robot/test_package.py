"""The robot side (tactile_torch.robot) imports no training dependency: torch, scikit-learn, scipy, numba;
and importing it loads none of its own optional packages either (onnxruntime, pyserial, cyclonedds,
rosbags are imported inside the functions that use them).

Each check runs in a fresh interpreter whose import system refuses those packages (a
``sys.meta_path`` finder that records and raises), as on a robot where only ``pip install
tactile-torch`` (numpy, onnxruntime, pyserial) is installed. The modules are discovered with
``pkgutil``, so a module added to the package later is covered without editing this test.
"""

from __future__ import annotations

import importlib
import json
import pkgutil
import subprocess
import sys
import textwrap

import tactile_torch.robot

BLOCKED = ("torch", "sklearn", "scipy", "numba")
DEFERRED = ("onnxruntime", "serial", "cyclonedds", "rosbags")
"""Packages the robot side uses only inside the functions that need them (an extra may be missing)."""
FLOOR_0 = (
    "tactile_torch._exports",
    "tactile_torch.exceptions",
    "tactile_torch.validation",
    "tactile_torch.validation._scalars",
)
"""The library's modules below the robot side that it may import (floor 0's helpers, torch-free)."""

_GUARD = f"""
import sys

BLOCKED = {BLOCKED!r}
attempts = []

class _Blocked:
    def find_spec(self, name, path=None, target=None):
        if name.split(".")[0] in BLOCKED:
            attempts.append(name)
            raise ImportError(f"{{name}} is not installed on this robot")
        return None

sys.meta_path.insert(0, _Blocked())
"""


def _run_blocked(code: str) -> dict:
    """Run ``code`` (which fills ``result``) under the guard; return ``result`` and the blocked attempts."""
    script = (
        _GUARD
        + "import json\nresult = {}\n"
        + textwrap.dedent(code)
        + "\nprint(json.dumps({'result': result, 'attempts': attempts}))\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def _robot_modules() -> list[str]:
    prefix = tactile_torch.robot.__name__ + "."
    return sorted(m.name for m in pkgutil.walk_packages(tactile_torch.robot.__path__, prefix))


def test_every_robot_module_is_discovered():
    modules = _robot_modules()
    assert "tactile_torch.robot.runtime" in modules and "tactile_torch.robot.stream.live" in modules
    assert {"tactile_torch.robot.files", "tactile_torch.robot.stream", "tactile_torch.robot.ros2"} <= set(
        modules
    )
    # every public name of the packages resolves, without torch (the subprocess test below imports them)
    for name in modules:
        package = importlib.import_module(name)
        for public in getattr(package, "__all__", ()) if hasattr(package, "__path__") else ():
            assert getattr(package, public) is not None


def test_robot_modules_import_without_training_dependencies():
    modules = _robot_modules()
    out = _run_blocked(
        f"""
        import importlib
        for name in {modules!r}:
            importlib.import_module(name)
        result["loaded"] = sorted(m for m in sys.modules if m.split(".")[0] in BLOCKED)
        result["deferred"] = sorted({{m.split(".")[0] for m in sys.modules}} & set({DEFERRED!r}))
        result["imported"] = sorted(m for m in sys.modules if m.startswith("tactile_torch."))
        """
    )
    assert out["attempts"] == [], f"robot modules tried to import {out['attempts']}"
    assert out["result"]["loaded"] == []
    assert out["result"]["deferred"] == [], "importing the robot side loaded optional packages"
    assert set(modules) <= set(out["result"]["imported"])
    # the robot side is the bottom floor: importing it loads nothing else of the library but floor 0's
    # helpers (the lazy exports of every __init__, the exceptions, the torch-free checks)
    others = [
        m for m in out["result"]["imported"] if not m.startswith("tactile_torch.robot") and m not in FLOOR_0
    ]
    assert others == [], f"robot modules imported {others}"


def test_robot_commands_start_without_training_dependencies():
    # The commands the robot CI job runs (.ci/robot: predict, stream, simulate-sensor) parse and
    # reach their robot modules with the training packages refused.
    out = _run_blocked(
        """
        import contextlib, io
        from tactile_torch.cli import main

        codes = {}
        for command in ("predict", "stream", "simulate-sensor"):
            with contextlib.redirect_stdout(io.StringIO()):
                try:
                    main([command, "--help"])
                except SystemExit as exit:
                    codes[command] = exit.code
        result["codes"] = codes
        """
    )
    assert out["attempts"] == [], f"the robot commands tried to import {out['attempts']}"
    assert out["result"]["codes"] == {"predict": 0, "stream": 0, "simulate-sensor": 0}


def test_guard_catches_a_module_that_imports_torch():
    # The guard is what the checks above rely on: a training module is refused and recorded.
    out = _run_blocked(
        """
        try:
            import tactile_torch.validation._tensors  # imports torch
            result["imported"] = True
        except ImportError as err:
            result["imported"] = False
            result["error"] = str(err)
        """
    )
    assert out["result"]["imported"] is False
    assert out["attempts"] and out["attempts"][0] == "torch"
