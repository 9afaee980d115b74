"""The core package imports without ROS, and the CLI answers --help without heavy imports."""
import subprocess
import sys


def test_import_model_does_not_import_rclpy():
    code = ("import sys, model, model.core, model.cli; "
            "bad = [m for m in ('rclpy', 'rclpy._rclpy_pybind11') if m in sys.modules]; "
            "assert not bad, bad; print('ok')")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "ok"


def test_cli_help_is_light():
    code = ("import sys, model.cli; model.cli.main(['--help']); "
            "assert 'torch' not in sys.modules, 'torch imported by --help'")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert "generate" in out.stdout
