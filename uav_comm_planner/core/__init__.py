"""The numerical core: the letter's model, its power and trajectory steps, and Algorithm 1.

No ROS and no MAVLink here: numpy, scipy, cvxpy and Clarabel only (and the package's errors).
"""
