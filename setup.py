"""ament_python / pip packaging of lubrig_ros."""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "lubrig_ros"
NODES = ["belt_drive", "plant", "analysis", "recorder", "replay", "view"]

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test", "bench"]),
    package_data={PACKAGE: ["py.typed"]},  # PEP 561: the package ships its type hints
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml") + glob("config/*.xml")),
        (f"share/{PACKAGE}/config/cases", glob("config/cases/*.yaml")),
        (f"share/{PACKAGE}/config/sweeps", glob("config/sweeps/*.yaml")),
        (f"share/{PACKAGE}/config/foxglove", glob("config/foxglove/*.json")),
        (f"share/{PACKAGE}/config/plotjuggler", glob("config/plotjuggler/*.xml")),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="lubrig_ros developers",
    maintainer_email="lubrig@example.org",
    description="Virtual lubricated test rig as ROS 2 nodes",
    license="Apache-2.0",
    python_requires=">=3.11",
    entry_points={
        "console_scripts": [
            "lubrig = lubrig_ros.cli.main:main",
            # lubrig_ros.nodes.entry: a Ctrl-C during the imports ends the node without a traceback
            *[f"{node} = lubrig_ros.nodes.entry:{node}" for node in NODES],
        ],
    },
)
