"""Why a route is refused: the one-line refusals of the road layer (and of the sweep's route draws) sorted
into a short list of reasons, so a sweep over many networks can count them (``irlsim scenario sweep``).

The reasons, in the order they are tried (the first whose pattern is in the message wins):

    no-car-lane   a route edge without a lane for passenger cars (only sidewalks, bike, bus or tram
                  lanes), or a network with no edge for cars at all
    lane-count    lanes that do not continue across a junction: no car lane of an edge leads into the next
    loop-lanes    a loop whose lanes do not join up (a lane added or dropped for good on a loop)
    too-short     a route shorter than an episode needs to start (50 m), or a network whose car routes all are
                  (the sweep's draws found none long enough)
    no-path       edges that do not connect (no path from one to the other, a route edge that does not
                  lead into the next), or no pair of car edges joined by a long enough path
    self-crossing a route that crosses itself without a junction (over a bridge, through a tunnel): the
                  networks carry no heights, so vehicles of the other level would overlap the ego. A
                  route through the same junction twice or back alongside itself loads (the route frame
                  projects by progress); older sweeps' records of those keep this reason
    no-start      a route that leaves the ego no place to start (the start's clearances from stop lines,
                  exits and checkpoints cover it): refused when the episode begins, not when it loads
    left-hand     a network that drives on the left
    network       a network that is missing or cannot be read
    other         any other one-line refusal (its message is kept in the sweep's table)

Lanes of different widths on one route and loops without a required lane are no longer refused (a loop's
mission is any lane); a record of an older sweep that gave them as reasons counts as 'other'.

A refusal is an :class:`irlsim.errors.IrlsimError` with one line; anything else (a Python traceback from
the road or the simulation) is a defect, counted apart as a crash, never as a refusal.
"""

from __future__ import annotations

#: reason -> substrings of the refusal message that mean it (tried in this order; 'other' last)
REASONS: dict[str, tuple[str, ...]] = {
    "no-car-lane": ("no lane for passenger cars", "admit passenger cars"),
    "lane-count": ("no car lane of '", "no lane of '"),
    "loop-lanes": ("the loop's lanes do not join up",),
    "too-short": ("shorter than the",),
    "no-path": ("no path from", "(no connection)", "no pair of car edges"),
    "self-crossing": ("crosses itself without a junction", "crosses itself or runs back alongside itself"),
    "no-start": ("leave no start on the route", "leaves no start for the ego"),
    "left-hand": ("drives on the left",),
    "network": ("is malformed", "not found"),
}
OTHER = "other"
#: every reason a sweep can report, in the order of its table
REASON_NAMES: tuple[str, ...] = (*REASONS, OTHER)


def refusal_reason(message: str) -> str:
    """The reason (one of :data:`REASON_NAMES`) of a one-line refusal message."""
    for reason, patterns in REASONS.items():
        if any(p in message for p in patterns):
            return reason
    return OTHER
