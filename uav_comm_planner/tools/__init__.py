"""Command-line tools: the `uav-comm-planner` command, its benchmark, figures and JSON files.

Imports the core and the vehicle side; never rclpy.
"""
