#!/usr/bin/env python3
"""Tests of idset.py on real voxvis.v1 messages (needs the stubs on PYTHONPATH)."""
import unittest

from voxvis.v1 import voxvis_pb2 as pb

import idset


class Decode(unittest.TestCase):
    def test_both_forms(self):
        self.assertEqual(idset.decode(pb.IdSet()), [])
        self.assertEqual(idset.form(pb.IdSet()), "empty")
        self.assertEqual(idset.decode(pb.IdSet(gaps=[3, 4, 1])), [3, 7, 8])
        self.assertEqual(idset.decode(pb.IdSet(gaps=[0, 1])), [0, 1])  # Id 0 is an id.
        # Bit k of byte j is id base + 8j + k, least significant bit first.
        bits = pb.IdSet(base=10, bits=bytes([0b101, 0, 0b10000000]))
        self.assertEqual(idset.form(bits), "bits")
        self.assertEqual(idset.decode(bits), [10, 12, 33])
        self.assertEqual(idset.decode(pb.IdSet(bits=b"\x01")), [0])  # Base 0.

    def test_a_set_through_the_wire(self):
        ids = [5, 6, 7, 9, 400, 401, 70000]
        gaps = [b - a for a, b in zip([0] + ids, ids)]
        sent = pb.IdSet(gaps=gaps).SerializeToString()
        self.assertEqual(idset.decode(pb.IdSet.FromString(sent)), ids)
        bits = bytearray((ids[-1] - 5) // 8 + 1)
        for i in ids:
            bits[(i - 5) // 8] |= 1 << (i - 5) % 8
        sent = pb.IdSet(base=5, bits=bytes(bits)).SerializeToString()
        self.assertEqual(idset.decode(pb.IdSet.FromString(sent)), ids)

    def test_malformed(self):
        for bad in (pb.IdSet(gaps=[1], bits=b"\x01"),
                    pb.IdSet(gaps=[1], base=4),
                    pb.IdSet(gaps=[1, 0]),
                    pb.IdSet(gaps=[2**32 - 1, 1]),
                    pb.IdSet(base=2**32 - 8, bits=b"\x00\x01")):
            with self.subTest(bad=bad), self.assertRaises(ValueError):
                idset.decode(bad)
        # Bits past the last id are fine while unset.
        self.assertEqual(idset.decode(pb.IdSet(base=2**32 - 8, bits=b"\x80\x00")), [2**32 - 1])


class Delta(unittest.TestCase):
    def test_apply(self):
        self.assertEqual(idset.apply_delta([], [], [4, 2]), [2, 4])
        self.assertEqual(idset.apply_delta([1, 3, 5], [3], [2, 9]), [1, 2, 5, 9])
        with self.assertRaisesRegex(ValueError, r"removed ids \[4\]"):
            idset.apply_delta([1, 3], [4], [])
        with self.assertRaisesRegex(ValueError, r"added ids \[3\]"):
            idset.apply_delta([1, 3], [], [3])

    def test_wake_list(self):
        wake = idset.WakeList()
        with self.assertRaisesRegex(ValueError, "not full"):
            wake.apply(pb.WakeList(version=1, woken=[2], size=1))
        wake.apply(pb.WakeList(full=True, ids=[1, 4], version=1, size=2))
        wake.apply(pb.WakeList(woken=[7], slept=[1], version=3, size=2))
        self.assertEqual(wake.ids, [4, 7])
        with self.assertRaisesRegex(ValueError, "version 3 after 3"):
            wake.apply(pb.WakeList(woken=[8], version=3, size=3))
        with self.assertRaisesRegex(ValueError, "the server says 5"):
            wake.apply(pb.WakeList(woken=[8], version=4, size=5))
        wake.apply(pb.WakeList(full=True, version=9, size=0))
        self.assertEqual(wake.ids, [])


if __name__ == "__main__":
    unittest.main()
