"""ament_python package `cable_winch_monitor`: console entry points and the ROS share files."""
from glob import glob

from Cython.Build import cythonize
from setuptools import Extension, find_packages, setup

PACKAGE = "cable_winch_monitor"

setup(
    name=PACKAGE,
    version="0.1.0",
    description="Pose, cable tensions, slack detection and shaft-wall alarms for a four-winch sinking platform",
    license="Apache-2.0",
    python_requires=">=3.10",
    packages=find_packages(include=[PACKAGE, f"{PACKAGE}.*"]),
    # the solvers' inner loops in C: a sample solved alone costs numpy calls, not arithmetic
    ext_modules=cythonize([Extension(f"{PACKAGE}.model.solvers.compiled", [f"{PACKAGE}/model/solvers/compiled.pyx"])]),
    install_requires=["numpy", "scipy", "pyyaml", "rosbags", "ruamel.yaml.clib", "mcap", "mcap-ros2-support"],
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", glob("config/*.yaml")),
        (f"share/{PACKAGE}/config/scenarios", glob("config/scenarios/*.yaml")),
        (f"share/{PACKAGE}/config/foxglove", glob("config/foxglove/*.json")),
        (f"share/{PACKAGE}/config/rviz", glob("config/rviz/*.rviz")),
        (f"share/{PACKAGE}/launch", glob("launch/*.py")),
    ],
    zip_safe=False,
    tests_require=["pytest"],
    entry_points={
        "console_scripts": [
            "cable-winch-monitor = cable_winch_monitor.__main__:run",
            "winch_monitor = cable_winch_monitor.nodes.winch_monitor:main",
        ],
    },
)
