"""The vehicle side: the vehicle's limits and timing, plans it flies, the WGS84 anchor of the
planning frame, and MAVLink (missions, their files, the link) in :mod:`.mavlink`.

Imports the core, pymavlink and pymap3d; never ROS.
"""
