"""Reading the id sets of a voxvis Tick stream (proto/voxvis/v1/voxvis.proto).

An IdSet holds ascending object ids in one of two forms, whichever the server
found smaller: `gaps` (the first id, then each id's difference from the one
before) or a bitset (`bits`, least significant bit first, from id `base`).
An empty set has neither. decode() reads both; apply_delta() and WakeList
rebuild the whole sets that PVS_DELTA answers and wake-list changes describe.
Malformed input raises ValueError: the server broke the contract.
"""

MAX_ID = 2**32 - 1


def form(ids):
    """'gaps', 'bits' or 'empty': which form the server chose."""
    return "gaps" if ids.gaps else "bits" if ids.bits else "empty"


def decode(ids):
    """The ids of an IdSet message, as an ascending list."""
    if ids.gaps and (ids.bits or ids.base):
        raise ValueError("holds both gaps and a bitset")
    if ids.bits:
        out = [ids.base + 8 * k + bit
               for k, byte in enumerate(ids.bits)
               for bit in range(8) if byte >> bit & 1]
    else:
        out, last = [], 0
        for i, gap in enumerate(ids.gaps):
            if i > 0 and gap == 0:
                raise ValueError(f"gap {i} is 0: ids are not strictly ascending")
            last += gap
            out.append(last)
    if out and out[-1] > MAX_ID:
        raise ValueError(f"id {out[-1]} is past {MAX_ID}")
    return out


def apply_delta(previous, removed, added):
    """`previous` (ascending ids) minus `removed` plus `added`, ascending."""
    have = set(previous)
    if missing := [i for i in removed if i not in have]:
        raise ValueError(f"removed ids {missing[:5]} were not in the set")
    if twice := [i for i in added if i in have]:
        raise ValueError(f"added ids {twice[:5]} were already in the set")
    return sorted(have.difference(removed).union(added))


class WakeList:
    """The scene's wake list, rebuilt from the WakeList messages of a stream:
    the dynamic objects whose positions the server needs (simulate those)."""

    def __init__(self):
        self.ids, self.version = [], None

    def apply(self, wake):
        if self.version is None and not wake.full:
            raise ValueError("the first wake list is not full")
        if self.version is not None and wake.version <= self.version:
            raise ValueError(f"wake version {wake.version} after {self.version}")
        if wake.full:
            self.ids = list(wake.ids)
        else:
            self.ids = apply_delta(self.ids, wake.slept, wake.woken)
        if len(self.ids) != wake.size:
            raise ValueError(f"wake list of {len(self.ids)} ids, the server says {wake.size}")
        self.version = wake.version
