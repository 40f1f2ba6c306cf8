"""What a check of one simulator step reports: its contacts, the pairs it checked, its counters."""
from collections.abc import Mapping
from dataclasses import dataclass, fields

from mjccd.scene import FrameCounters

COUNTER_NAMES = tuple(f.name for f in fields(FrameCounters))  # the counters every check reports
_COUNTER_INDEX = {name: k for k, name in enumerate(COUNTER_NAMES)}


class StepCounters(Mapping):
    """The pair outcome counters of one check, read-only: :class:`mjccd.scene.FrameCounters` field names (in
    that order) to counts.  It keeps the counts as one list, made once per check, and equals the dict of the
    same counts."""

    __slots__ = ("_counts",)

    def __init__(self, counts):
        self._counts = counts

    def __getitem__(self, name):
        return self._counts[_COUNTER_INDEX[name]]

    def __iter__(self):
        return iter(COUNTER_NAMES)

    def __len__(self):
        return len(COUNTER_NAMES)

    def __repr__(self):
        return repr(dict(self))


@dataclass(frozen=True, eq=False)
class StepContact:
    """First contact of one pair of bodies within one simulator step.

    Attributes:
        time: simulation time of the contact in seconds.
        fraction: the same instant as a fraction in [0, 1] of the step.
        bodies: the two body names (for an unnamed body ``#id`` and its first named geom: ``#4 (ball)``).
        body_ids: the two MuJoCo body ids.
        ellipsoids: the two ellipsoid indices in the monitor's :class:`EllipsoidSet`; for a contact with a
            plane, the ellipsoid's index and -1.
        point: (3,) world contact point, None when the pair was not separate at the step start; for an
            uncertain contact, an estimate: where the two nearly touch at the bracket's start.
        normal: (3,) unit world normal pointing out of ``bodies[0]``, None likewise.
        status_at_start: "separate", "touching" or "overlapping" at the step start.
        certainty: "certified", or "uncertain" when the exact solver hit one of its limits on
            this pair: then the contact is only possible, somewhere in ``bracket``, and ``time``
            and ``fraction`` are the start of that bracket (never read it as "no contact").
        bracket: (lo, hi) simulation times in seconds holding every possible first contact
            when uncertain (lo == hi when the first contact itself is known); None when certified.
        pair: the index of the pair in the checker's pair list (``pairs[pair]`` is ``ellipsoids``); for a
            plane, ``len(pairs)`` plus its row in ``plane_pairs``.
        geom: the plane geom of a contact with a plane (``bodies[1]`` is its body; the normal points
            out of the ellipsoid, into the plane); -1 for a pair of ellipsoids.
        geoms: in geoms mode, the two geom ids that touch (``geom`` is then the second when it is a plane);
            (-1, -1) for ellipsoids.
        elements: in geoms mode, the touching element of each geom ("face +x", "rim -z", "side", ...).
    """

    time: float
    fraction: float
    bodies: tuple
    body_ids: tuple
    ellipsoids: tuple
    point: object
    normal: object
    status_at_start: str
    certainty: str = "certified"
    bracket: tuple = None
    pair: int = -1
    geom: int = -1
    geoms: tuple = (-1, -1)
    elements: tuple = None


@dataclass(frozen=True, eq=False)
class StepReport:
    """Everything one check found: the first contact (or None), all colliding pairs when asked, counts.

    ``pairs_uncertain`` counts the pairs on which the exact solver hit a limit (see
    :attr:`StepContact.certainty`), including those whose bracket starts after the first contact.
    ``unstable`` is True when MuJoCo met a bad position, velocity or acceleration within the step
    (its ``mjWARN_BADQPOS``/``QVEL``/``QACC`` warnings, a state left NaN or infinite) and, unless
    autoreset is disabled, reset the data: the jump back to the reset pose is no motion, so nothing
    is checked across it (no contact, no pair counted), as :class:`~mjccd.mujoco.GuardReport` reports it.
    ``counters`` (when the check gives them): the pair outcomes as :class:`mjccd.scene.FrameCounters`
    field names to counts, a read-only mapping (:class:`StepCounters`).
    """

    first: object
    contacts: tuple
    pairs_checked: int
    pairs_solved: int
    pairs_uncertain: int = 0
    unstable: bool = False
    counters: dict = None


UNSTABLE_REPORT = StepReport(None, (), 0, 0, 0, True)  # what a step that met a bad state reports


