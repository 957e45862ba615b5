"""The mission layer, without ROS: what to plan for which vehicle (:mod:`.request`), the one
planning pipeline that the node and the command line both call (:mod:`.pipeline`), and the
mission in flight, its clock and the slots flown (:mod:`.progress`)."""
