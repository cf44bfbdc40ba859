"""A query's start and goals, checked before any planning: within bounds, free, and at least the clearance the motion
must keep from everything; a refusal names what is wrong (the coordinate, the bodies) and how to mend it."""

from __future__ import annotations

import numpy as np

from app.errors import InvalidEndpoint
from app.scene.shapes import CONTACT


def check_endpoint(checker, q, what: str, clearance: float = CONTACT) -> np.ndarray:
    """A start or goal as a vector; wrong length or non-finite -> UserError, out of bounds, colliding or nearer
    than `clearance` to anything -> InvalidEndpoint naming the coordinate or the bodies.

    Touching (signed distance 0: a maze hull on the outer wall at its bound), or nearer than the clearance the
    motion must keep, is refused too, although the collision check calls it free: no motion out of it can be
    certified, and a query from it would spend its whole budget before failing. Refused rather than moved off,
    because which way is "off" is the user's call (a tool on a part means to touch it); the message says how close
    the bodies are, so a nudge is easy."""
    q = checker.space.check_configuration(q, what)
    bad = checker.space.out_of_bounds(q)
    code = "START_STATE_IN_COLLISION" if what == "start" else "GOAL_IN_COLLISION"
    if bad:
        raise InvalidEndpoint(
            f"{what} is out of bounds: {'; '.join(bad)}",
            "START_STATE_INVALID" if what == "start" else "GOAL_STATE_INVALID",
        )
    if not checker.is_free(q):
        pairs = checker.diagnostics.colliding_bodies(q)
        if not pairs:  # faces that touch exactly: a collision to the check, no penetration to name; name the contact
            pairs = [(a, b) for a, b, _ in checker.diagnostics.touching(q)]
        touching = ", ".join(f"{a} with {b}" for a, b in pairs[:4]) + (" ..." if len(pairs) > 4 else "")
        raise InvalidEndpoint(
            f"{what} is in collision: {touching or 'contact reported by the checker'}{_own_links(checker, pairs)}",
            code,
        )
    contacts = checker.diagnostics.touching(q, max(clearance, CONTACT))
    if contacts:
        named = ", ".join(f"{a} with {b} at {d:.2g}" for a, b, d in contacts[:4]) + (
            " ..." if len(contacts) > 4 else ""
        )
        own = _own_links(checker, contacts)
        if contacts[0][2] <= CONTACT:
            raise InvalidEndpoint(
                f"{what} touches (signed distance <= {CONTACT:g}): {named}; move it off the contact{own}", code
            )
        raise InvalidEndpoint(
            f"{what} is nearer than the clearance {clearance:g} the motion must keep: {named}; move it off, or "
            f"plan with a smaller clearance (--clearance){own}",
            code,
        )
    return checker.space.wrap(q)


def _own_links(checker, pairs) -> str:
    """For an endpoint refused over body pairs (scoped names first in each item): if two links of the robot are one
    of them, the end of the message saying how to stop checking that pair, which no move of the endpoint can help
    when the links touch by design (at a joint); else nothing."""
    links = getattr(checker.scene, "robot_links", {})
    own = [(links[a], links[b]) for a, b, *_ in pairs if a in links and b in links]
    if not own:
        return ""
    a, b = own[0]
    return (
        f"; {a} and {b} are links of the robot: if that is by design, leave the pair out with an SRDF (--srdf FILE "
        f'holding <disable_collisions link1="{a}" link2="{b}"/>; srdf: in a scene file) or do not check '
        "self-collision (--no-self-collision; collisions: environment)"
    )


def check_goals(checker, goal, clearance: float = CONTACT) -> np.ndarray:
    """One goal, or several (k, dim) of which the query may reach any (every IK solution of a tool pose), as rows.
    A single bad goal is refused as check_endpoint refuses it; among several, those that are out of bounds or collide
    are left out, and only when none is left is the first one's fault raised."""
    try:
        several = np.ndim(np.asarray(goal, float)) == 2
    except (TypeError, ValueError):  # ragged or not numbers: check_endpoint says what is wrong
        several = False
    if not several:
        return check_endpoint(checker, goal, "goal", clearance)[None, :]
    kept, faults = [], []
    for q in goal:
        try:
            kept.append(check_endpoint(checker, q, "goal", clearance))
        except InvalidEndpoint as fault:
            faults.append(fault)
    if not kept:
        if len(faults) == 1:
            raise faults[0]
        raise InvalidEndpoint(f"none of {len(faults)} goals is valid; the first: {faults[0]}", faults[0].code)
    return np.array(kept)
