#!/usr/bin/env python3
"""Tests of region.py: the worked numbers of docs/server.md."""
import unittest

import region


class Region(unittest.TestCase):
    def test_a_128_tick_shooter(self):
        extent, horizon = region.region_for(0.060, 1 / 128, 2 / 128, 250.0, 9.0)
        self.assertAlmostEqual(horizon, 0.0834, places=4)
        self.assertEqual(round(extent[0]), 21)
        self.assertEqual(extent[0], extent[2])
        self.assertEqual(extent[1], 9.0)

    def test_a_quake_like_game(self):
        extent, horizon = region.region_for(0.100, 0.025, 0.050, 320.0, 14.0)
        self.assertAlmostEqual(horizon, 0.175)
        self.assertEqual(round(extent[0]), 56)

    def test_a_higher_ping_gets_a_larger_region(self):
        near, _ = region.region_for(0.020, 1 / 64, 0.0, 300.0, 0.0)
        far, _ = region.region_for(0.200, 1 / 64, 0.0, 300.0, 0.0)
        self.assertGreater(far[0], 5 * near[0])

    def test_bad_values(self):
        for bad in (-1.0, float("nan"), float("inf")):
            with self.assertRaises(ValueError):
                region.answer_lifetime(bad, 0.01, 0.0)
        with self.assertRaises(ValueError):
            region.region_for(0.05, 0.01, 0.0, -5.0, 0.0)


if __name__ == "__main__":
    unittest.main()
