"""How a deploy run ends: outcomes, their exit codes (the documented table) and the faults that stop the base.

A fault is not a user mistake (``UserError``, exit 2, raised before anything moves) and not a bug (any other
exception: the base is stopped, the traceback shown, exit 1): it is the safety layer doing its job. The loop
stops the base, writes the summary with the fault's ``outcome`` and exits with its code.
"""

from __future__ import annotations

from ..errors import EXIT_SIGINT, EXIT_SIGTERM, EXIT_USAGE

# outcome -> exit code; docs/deploy.md prints this table
EXIT_CODES: dict[str, int] = {
    "success": 0,  # joined the group (the task's own success rule on the estimated group)
    "exception": 1,  # a bug (policy, detector, loop): base stopped, traceback printed
    "bad_input": EXIT_USAGE,  # flags, files, robot address or services: nothing moved
    "duration": 3,  # --duration elapsed without success
    "human_too_close": 4,  # a tracked human within --stop-distance of the footprint
    "stale_frame": 5,  # newest camera frame older than --stale (camera frozen or starved)
    "stale_odometry": 6,  # odometry older than --stale
    "connection_lost": 7,  # the robot's session closed (robot process died, network down)
    "robot_not_responding": 8,  # a bounded call timed out (robot process frozen, network stalled)
    "sigint": EXIT_SIGINT,
    "sigterm": EXIT_SIGTERM,
}


class DeployFault(Exception):
    """The safety layer stopped the run; ``outcome`` names the case (a key of ``EXIT_CODES``)."""

    outcome = "fault"

    @property
    def exit_code(self) -> int:
        return EXIT_CODES[self.outcome]


class HumanTooClose(DeployFault):
    outcome = "human_too_close"


class StaleFrame(DeployFault):
    outcome = "stale_frame"


class StaleOdometry(DeployFault):
    outcome = "stale_odometry"


class ConnectionLost(DeployFault):
    outcome = "connection_lost"


class RobotNotResponding(DeployFault):
    outcome = "robot_not_responding"
