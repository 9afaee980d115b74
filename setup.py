"""ament_python package: the ROS plumbing (artformer_ros) and the ROS-free core (model)."""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = "artformer_ros"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(include=["artformer_ros", "artformer_ros.*", "model", "model.*"]),
    package_data={"model": ["weights/*.pt", "weights/*.json",
                            "weights/*.md", "assets/*", "metrics/*.txt"]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="artformer_ros developers",
    maintainer_email="dev@artformer-ros.invalid",
    description="ArtFormer articulated-object generation for ROS 2 (text/image -> URDF + meshes).",
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "artformer = model.cli:main",
            "artformer_generator_node = artformer_ros.generator_node:main",
            "artformer_request = artformer_ros.request:main",
            # the earlier names, kept for one more release
            "generator_node = artformer_ros.generator_node:main_old_name",
            "request = artformer_ros.request:main_old_name",
        ],
    },
)
