"""The vehicle side: the WGS84 anchor of the planning frame and MAVLink mission files.

Imports the core, pymavlink and pymap3d; never ROS.
"""
