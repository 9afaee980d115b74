"""`colcon build` builds the package (ament_python) into a temp install tree, and the installed
`lib/artformer_ros/artformer_generator_node` starts from that tree with the shipped params YAML and
serves a request (example backend)."""
import os
import random
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

rclpy = pytest.importorskip("rclpy")

from artformer_ros.client import GeneratorClient, stop_node  # noqa: E402

pytestmark = pytest.mark.ros
REPO = Path(__file__).resolve().parent.parent
PKG = "artformer_ros"


def _colcon() -> str:
    exe = Path(sys.executable).parent / "colcon"
    found = str(exe) if exe.exists() else shutil.which("colcon")
    if not found:
        pytest.skip("colcon is not installed")
    return found


def _sourced_env(install: Path, base: dict) -> dict:
    """The environment after `source <install>/setup.bash` (what a ROS user does)."""
    out = subprocess.run(["bash", "-c", f"source '{install}/setup.bash' && env -0"],
                         capture_output=True, env=base, timeout=60, check=True)
    return dict(item.split("=", 1) for item in out.stdout.decode().split("\0") if "=" in item)


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("colcon")
    env = {**os.environ, "AMENT_PREFIX_PATH": str(REPO / ".venv"),
           "PATH": f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}"}
    out = subprocess.run([_colcon(), "--log-base", str(tmp / "log"), "build",
                          "--base-paths", str(REPO), "--packages-select", PKG,
                          "--build-base", str(tmp / "build"),
                          "--install-base", str(tmp / "install")],
                         capture_output=True, text=True, env=env, cwd=tmp, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr
    assert f"Finished <<< {PKG}" in out.stdout
    return tmp, tmp / "install", env


def test_install_tree_has_the_executables_and_share_files(installed):
    _, install, _ = installed
    prefix = install / PKG
    for exe in ("artformer_generator_node", "artformer_request", "generator_node", "request"):
        path = prefix / "lib" / PKG / exe
        assert path.is_file() and os.access(path, os.X_OK), path
    share = prefix / "share" / PKG
    for rel in ("package.xml", "config/artformer.yaml", "launch/artformer.launch.py"):
        assert (share / rel).is_file(), rel
    assert (prefix / "share/ament_index/resource_index/packages" / PKG).is_file()


def test_installed_generator_node_starts_and_serves(installed):
    tmp, install, env = installed
    domain = str(random.SystemRandom().randint(1, 100))
    run_env = _sourced_env(install, {**env, "ROS_DOMAIN_ID": domain,
                                     "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"})
    pyver = f"python{sys.version_info[0]}.{sys.version_info[1]}"
    site = install / PKG / "lib" / pyver / "site-packages"
    where = subprocess.run([sys.executable, "-c", "import artformer_ros, model; "
                            "from ament_index_python.packages import get_package_share_directory "
                            "as g; print(artformer_ros.__file__); print(model.__file__); "
                            f"print(g('{PKG}'))"],
                           capture_output=True, text=True, env=run_env, cwd=tmp, timeout=60)
    lines = where.stdout.split()
    assert where.returncode == 0 and lines[0].startswith(str(site)) and \
        lines[1].startswith(str(site)), where.stdout + where.stderr
    share = Path(lines[2])
    assert share == install / PKG / "share" / PKG

    exe = install / PKG / "lib" / PKG / "artformer_generator_node"
    log = tmp / "node.log"
    with open(log, "w") as f:
        proc = subprocess.Popen([str(exe), "--ros-args", "--params-file",
                                 str(share / "config" / "artformer.yaml"),
                                 "-p", "backend:=example", "-p", f"output_dir:={tmp / 'out'}"],
                                env=run_env, cwd=tmp, stdout=f, stderr=subprocess.STDOUT)
    saved = os.environ.get("ROS_DOMAIN_ID")
    os.environ["ROS_DOMAIN_ID"] = domain
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    try:
        client = GeneratorClient(context=ctx)
        assert client.wait_ready(60), (client.status, log.read_text())
        res = client.wait_result(client.send_text("a cabinet"), 60)
        assert res is not None and res["status"] == "done", res
        assert res["output_dir"].startswith(str(tmp / "out"))
        client.close()
        assert stop_node(proc, 30) == 0
    finally:
        if proc.poll() is None:
            proc.kill()
        rclpy.try_shutdown(context=ctx)
        if saved is None:
            os.environ.pop("ROS_DOMAIN_ID", None)
        else:
            os.environ["ROS_DOMAIN_ID"] = saved
    text = log.read_text()
    assert "backend=example" in text and "Traceback" not in text
