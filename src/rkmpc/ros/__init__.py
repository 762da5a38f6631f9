"""ROS 2 for rkmpc: ``rkmpc node`` drives a car with any controller, ``rkmpc sim-node`` is the simulated car.

Optional: ``pip install 'rkmpc[ros]'`` (ROS 2 Kilted's wheels from PyPI) and ``make ros``
(ackermann_msgs, generated from its definition into the venv). The core package never imports
this one. The wheels need no sourced workspace: rclpy's start-up hook (``ros_wheels_bootstrapper``)
restarts the interpreter once with the venv's ``lib`` and the wheels' library folders on
``LD_LIBRARY_PATH``; the middleware is Fast DDS (``RMW_IMPLEMENTATION`` unset or
``rmw_fastrtps_cpp``). ``ROS_DOMAIN_ID`` and ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`` keep a
loop on one machine to itself.

Modules without ROS: :mod:`~rkmpc.ros.config` (the per-car YAML), :mod:`~rkmpc.ros.safety`,
:mod:`~rkmpc.ros.latency`, :mod:`~rkmpc.ros.driver` (one period of the node),
:mod:`~rkmpc.ros.conversions`, :mod:`~rkmpc.ros.record`, :mod:`~rkmpc.ros.sim_config`,
:mod:`~rkmpc.ros.sim_plant`. With ROS: :mod:`~rkmpc.ros.node`, :mod:`~rkmpc.ros.remote`,
:mod:`~rkmpc.ros.sim_node`.
"""
