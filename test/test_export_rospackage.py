"""ROS description package: `colcon build` installs it, and the installed URDF (package://
URIs resolved through the ament index) loads in yourdfpy, pybullet and MuJoCo with the poses
of the source object."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from lxml import etree

from model.core.example import example_objects
from model.export.rospackage import export_ros_package, package_name
from model.export.urdf import export_object
from model.export.urdfmodel import ConvertError

pytestmark = pytest.mark.ros
REPO = Path(__file__).resolve().parent.parent


def _colcon() -> str:
    exe = Path(sys.executable).parent / "colcon"
    found = str(exe) if exe.exists() else shutil.which("colcon")
    if not found:
        pytest.skip("colcon is not installed")
    return found


@pytest.fixture(scope="module")
def built(tmp_path_factory, exported_examples):
    tmp = tmp_path_factory.mktemp("rospkg")
    pkgs = {}
    for name, (_, res) in exported_examples.items():
        shutil.copytree(res.out_dir, tmp / "objects" / name)
        pkgs[name] = export_ros_package(tmp / "objects" / name, tmp / "ws" / "src" / f"{name}_description",
                                        name=name)
    env = {**os.environ, "AMENT_PREFIX_PATH": str(REPO / ".venv"),
           "PATH": f"{Path(sys.executable).parent}:{os.environ.get('PATH', '')}"}
    out = subprocess.run([_colcon(), "--log-base", str(tmp / "log"), "build",
                          "--base-paths", str(tmp / "ws" / "src"),
                          "--build-base", str(tmp / "build"), "--install-base", str(tmp / "install")],
                         capture_output=True, text=True, env=env, cwd=tmp, timeout=300)
    assert out.returncode == 0, out.stdout + out.stderr
    # the folder the packages came from is gone: the installed tree must be self-contained
    shutil.rmtree(tmp / "objects")
    return tmp, pkgs, env


def test_source_package_layout(built):
    _, pkgs, _ = built
    res = pkgs["cabinet"]
    assert res.package == "cabinet_description"
    root = Path(res.out_dir)
    for rel in ("package.xml", "setup.py", "setup.cfg", "resource/cabinet_description",
                "metadata.json"):
        assert (root / rel).is_file(), rel
    xml = etree.parse(str(root / "package.xml")).getroot()
    assert xml.findtext("name") == "cabinet_description"
    assert xml.find("export/build_type").text == "ament_python"
    uris = [m.get("filename") for m in etree.parse(res.urdf).getroot().iter("mesh")]
    assert uris and all(u.startswith("package://cabinet_description/meshes/") for u in uris)
    assert {u.rsplit("/", 1)[1] for u in uris} == set(res.meshes)
    assert set(res.meshes) == {p.name for p in (root / "meshes").iterdir()}


def test_colcon_installs_urdf_and_meshes(built):
    tmp, pkgs, _ = built
    for name, res in pkgs.items():
        share = tmp / "install" / res.package / "share" / res.package
        assert res.share_urdf == f"{res.package}/urdf/{Path(res.urdf).name}"
        assert (share / "urdf" / Path(res.urdf).name).is_file()
        for mesh in res.meshes:
            assert (share / "meshes" / mesh).is_file(), mesh
        assert (tmp / "install" / res.package / "share/ament_index/resource_index/packages"
                / res.package).is_file()


def test_installed_urdf_loads_in_the_simulators(built):
    tmp, pkgs, env = built
    out = subprocess.run(["bash", "-c", f"source '{tmp}/install/setup.bash' && env -0"],
                         capture_output=True, env=env, timeout=60, check=True)
    run_env = dict(item.split("=", 1) for item in out.stdout.decode().split("\0") if "=" in item)
    code = (
        "import sys; from pathlib import Path\n"
        "from ament_index_python.packages import get_package_share_directory as share\n"
        "from model.core.example import example_objects\n"
        "from model.export.simcheck import check_urdf\n"
        "objs = example_objects()\n"
        "oks = []\n"
        "for name in ('cabinet', 'bottle'):\n"
        "    d = Path(share(name + '_description'))\n"
        "    urdf = next((d / 'urdf').glob('*.urdf'))\n"
        "    rep = check_urdf(urdf, objs[name])\n"
        "    print(name, rep.ok, rep.summary().replace(chr(10), ' | '))\n"
        "    oks.append(rep.ok)\n"
        "sys.exit(0 if all(oks) else 1)\n")
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         env=run_env, cwd=tmp, timeout=240)
    assert res.returncode == 0, res.stdout + res.stderr
    assert res.stdout.count(" True ") == 2, res.stdout


def test_names():
    assert package_name("cabinet") == "cabinet_description"
    assert package_name("cabinet_description") == "cabinet_description"
    for bad in ("Cabinet", "1cab", "cab-inet", "cab__x", ""):
        with pytest.raises(ConvertError, match="REP 144"):
            package_name(bad)


def test_cli(tmp_path):
    export_object(example_objects()["bottle"], tmp_path / "bottle", preview=False)
    out = subprocess.run([sys.executable, "-m", "model", "convert", str(tmp_path / "bottle"),
                          "--to", "ros-package", "--name", "my_bottle"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert (tmp_path / "bottle" / "ros" / "my_bottle_description" / "package.xml").is_file()
    out = subprocess.run([sys.executable, "-m", "model", "convert", str(tmp_path / "bottle"),
                          "--to", "ros-package", "--name", "My-Bottle"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 1 and "REP 144" in out.stderr
