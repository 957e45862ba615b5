"""Typed errors of the planner; each message says what is wrong and what to change."""


class PlannerError(Exception):
    """Base of every error the planner raises on purpose."""


class InvalidScenarioError(PlannerError, ValueError):
    """A scenario or solver setting is out of its domain (NaN, non-positive, duplicates...)."""


class InvalidChannelError(InvalidScenarioError):
    """A channel name that is not one the planner knows ('free-space', 'los:urban', ...)."""


class SelfCrossingError(InvalidScenarioError):
    """A polygon zone that crosses itself; ``edges``: the two edges that meet, 0-based (edge k
    from vertex k to the next), so that a caller that built the polygon can name them its
    own way (a fence names the file's edges, not the pieces they were cut into)."""

    def __init__(self, message: str, edges: tuple[int, int]):
        super().__init__(message)
        self.edges = edges

    def __reduce__(self):
        return type(self), (str(self), self.edges)


class InfeasibleHorizonError(InvalidScenarioError):
    """The goal cannot be reached from the start within the horizon at the speed limit."""


class WalledInError(InfeasibleHorizonError):
    """No path keeps the zones' margin between two points, however long the horizon: more
    slots or a slower speed cannot help (the start or the goal is walled in)."""


class SolverError(PlannerError, RuntimeError):
    """A convex sub-problem was not solved to optimality (numerical failure of the solver)."""


class MissionExportError(PlannerError):
    """A mission file could not be written; the previous file, if any, is left untouched."""


class MissionFileError(PlannerError):
    """A mission file could not be read: missing, malformed, or holding items not uploaded."""


class VehicleLinkError(PlannerError):
    """The vehicle's MAVLink link failed or the vehicle refused what was sent; says which."""


class VehicleLinkLostError(VehicleLinkError):
    """The link went down during a transfer (closed, reset, an error of its socket or port, or
    silent: a cut UDP or serial link only goes quiet); what was being sent is worth sending
    again once the link is back, unlike a refusal."""


class InvalidLinkUrlError(VehicleLinkError, ValueError):
    """A vehicle link URL that is not one the planner opens (scheme, host, port, device)."""


class MissionTooFarError(VehicleLinkError):
    """A mission whose home or first waypoint is too far from the vehicle to be its mission."""


class ComputeBudgetError(InvalidScenarioError):
    """A problem larger than the compute budget (nodes x slots) was refused before any work."""


class PlanCancelledError(PlannerError):
    """A plan was given up between two steps because its caller asked it to stop."""


class FenceFileError(MissionFileError):
    """A fence file could not be read: missing, malformed, or holding a zone that is not one."""
