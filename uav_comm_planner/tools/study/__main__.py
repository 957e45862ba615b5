"""``python -m uav_comm_planner.tools.study``: the ``montecarlo`` command on its own.

The tasks sent to the workers refer to the study's modules by their own names, which the
workers import, never to this ``__main__``.
"""

import sys

from uav_comm_planner.tools.study.command import main

sys.exit(main())
