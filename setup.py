# Used by catkin_python_setup() only (catkin puts devel/lib/python3/dist-packages on PYTHONPATH).
from catkin_pkg.python_setup import generate_distutils_setup
from setuptools import setup

setup(
    **generate_distutils_setup(
        packages=[
            "kinect_pipeline",
            "kinect_pipeline.bags",
            "kinect_pipeline.simulation",
            "kinect_pipeline.evaluation",
            "kinect_pipeline.tools",
            "kinect_pipeline.cli",
        ],
        package_dir={"": "src"},
        package_data={"kinect_pipeline": ["py.typed", "_core.pyi"]},
    )
)
