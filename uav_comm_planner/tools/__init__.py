"""Command-line tools: the `uav-comm-planner` command, its figures and JSON files, Monte Carlo
studies (the benchmark is in devtools/, beside the package).

Imports the core and the vehicle side; never rclpy.
"""
