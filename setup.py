"""ament_python package phid_ros; also a plain pip-installable package (no ROS needed)."""

from glob import glob

from setuptools import find_packages, setup

package_name = "phid_ros"


def data(folder: str, pattern: str = "*") -> list[str]:
    return [f for f in glob(f"{folder}/{pattern}")]


setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(include=["phid_ros", "phid_ros.*"]) + ["phid_ros.msg_schemas_data"],
    # The .msg files live once, in msg_schemas/ (the phid_msgs interface package).
    # They ship inside the wheel as phid_ros/msg_schemas_data/ so the rosbags
    # typestore finds them on a machine without ROS.
    package_dir={"phid_ros.msg_schemas_data": "msg_schemas"},
    package_data={"phid_ros.msg_schemas_data": ["msg/*.msg"]},
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/launch", data("launch", "*.py")),
        ("share/" + package_name + "/config", data("config", "*.yaml")),
        ("share/" + package_name + "/msg_schemas/msg", data("msg_schemas/msg", "*.msg")),
    ],
    python_requires=">=3.11",
    install_requires=[
        "numpy>=1.26",
        "scipy>=1.11",
        "rosbags>=0.10",
        "mcap>=1.1",
        "zstandard>=0.21",
        "rich>=13.0",
        "matplotlib>=3.6",
        # one engine for parallel work (phid fleet, a diagnosis round's candidates): a local
        # cluster on a laptop, an existing cluster by its scheduler address
        "dask>=2024.1",
        "distributed>=2024.1",
        "bokeh>=3.1",  # the Dask dashboard phid fleet prints the address of
        "pyyaml>=6.0",  # fleet inventories as YAML lists
        # the diagnosis play-in compiled (phid_ros/sim/kernel.py): 6-9x a numpy play-in; without
        # it (or with PHID_NO_JIT=1) the numpy plant runs, the same numbers, slower
        "numba>=0.60",
        # one BLAS thread per job thread while a diagnosis's candidates run on threads (cluster.py)
        "threadpoolctl>=3.1",
        # COMTRADE (IEEE C37.111) reading for phid import-comtrade: a maintained parser, not ours
        "comtrade>=0.1",
    ],
    extras_require={
        # andes: the independent simulator the exported planning records are checked in
        "test": ["pytest>=7.4", "andes>=1.9"],
    },
    zip_safe=True,
    maintainer="phid_ros maintainers",
    maintainer_email="phid@example.org",
    description="Port-Hamiltonian identification of synchronous generators from sensor streams (ROS 2 Jazzy).",
    license="Apache-2.0",
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "phid = phid_ros.cli.main:entry",
            "ingest_node = phid_ros.nodes.ingest_node:main",
            "recalibration_node = phid_ros.nodes.recalibration_node:main",
        ],
    },
)
