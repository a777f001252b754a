"""A player's region from its round trip (docs/server.md, "Hiding players
over a network"): how long an answer stays in use, and the eye box and
horizon that cover it."""


def answer_lifetime(round_trip_s, tick_s, interpolation_s):
    """Seconds an answer is in use: the round trip, the client's
    interpolation delay, and one tick (the next answer replaces it)."""
    for name, v in (("round_trip_s", round_trip_s), ("tick_s", tick_s), ("interpolation_s", interpolation_s)):
        if not (v >= 0.0) or v == float("inf"):
            raise ValueError(f"{name} must be finite and >= 0, got {v}")
    return round_trip_s + tick_s + interpolation_s


def region_for(round_trip_s, tick_s, interpolation_s, speed, vertical):
    """(eye_extent [hx, hy, hz], horizon_s) for a player who runs at up to
    `speed` units a second and whose eye moves up to `vertical` units (half
    a jump's or crouch's travel) within an answer's lifetime. Every
    direction counts too: set omnidirectional."""
    if not (speed >= 0.0) or not (vertical >= 0.0):
        raise ValueError("speed and vertical must be >= 0")
    life = answer_lifetime(round_trip_s, tick_s, interpolation_s)
    reach = speed * life
    return [reach, vertical, reach], life
