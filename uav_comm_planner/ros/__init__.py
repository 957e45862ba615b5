"""The ROS 2 adapter: the planner node, its parameters, message conversions and a sender.

The only part of the package that imports rclpy and ROS messages.
"""
