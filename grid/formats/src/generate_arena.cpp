// generate_arena.cpp — the arena preset (voxvis/generate.h, make_arena): a
// level like the ones players fight in, in Quake's units (a player is a box
// of 32 x 32 x 56 running at 320 units a second).
//
// The plan: rows of square rooms (496 units inside, walls 16 thick), a
// corridor 128 wide between every two rows, two storeys (floor 0 at y = 0,
// floor 1 at y = 192 under a roof at 384). About half the rooms have an
// upper floor, reached by a stair of 12 steps through a hole in it; the
// others are halls two storeys high with four pillars. Every corridor has a
// walkway over it on floor 1. Doorways (96 x 128) join each room to its
// corridors and to the rooms beside it, on floor 0 always and on floor 1
// where both sides have one. Every coordinate of a wall, slab or doorway is
// a multiple of 16, the grid's voxel, so walls fill whole voxels.
//
// Players and the camera walk a graph of the level: room centres and points
// of the corridors' centre lines, joined by L-shaped paths through the
// doorways. The paths keep 16 units (half a player) clear of every wall,
// pillar, stair and stair hole, which tests/grid/test_generate.cpp checks.
#include <algorithm>
#include <cmath>
#include <numbers>
#include <vector>

#include <glm/geometric.hpp>

#include "voxvis/generate.h"
#include "voxvis/rng.h"

namespace voxvis {
namespace {

constexpr double kWall = 16.0;                     // Walls and slabs: one voxel thick.
constexpr double kInside = 496.0;                  // A room from wall to wall.
constexpr double kPitchX = kInside + kWall;        // 512: room to room along x.
constexpr double kCorridor = 128.0;                // Between two rows of rooms.
constexpr double kPitchZ = kPitchX + kCorridor + kWall;  // 656: row to row along z.
constexpr double kStorey = 192.0;                  // Floor 1's walking level.
constexpr double kRoof = 384.0;                    // The roof slab's underside.
constexpr double kDoorHalf = 48.0, kDoorHigh = 128.0;
constexpr int kSteps = 12;                         // 16 high, 16 deep each.
constexpr double kStairX = 96.0, kStairZ0 = 32.0;  // The stair: inside x [0, 96], z [32, 224].
constexpr double kPillarHalf = 32.0;  // 64 across: whole voxels.
constexpr Vec3 kPlayerHalf{16.0, 28.0, 16.0};
constexpr double kRun = 320.0;  // Units a second, players and camera.
constexpr double kEye = 48.0;   // Above the floor.

/// A point of the walk graph on the floor plane: x and z.
struct P2 {
  double x = 0.0, z = 0.0;
};

struct Room {
  int rx = 0, rz = 0;
  bool upper = false;       // Has floor 1 (and a stair); else a hall with pillars.
  double x0 = 0.0, z0 = 0.0;  // Inside's lower corner.
  P2 centre() const { return {x0 + 0.5 * kInside, z0 + 0.5 * kInside}; }
};

struct Door {
  double at = 0.0;  // Centre along the wall.
  double y0 = 0.0;  // Floor of the doorway (0 or kStorey).
};

/// One storey's walk graph: nodes, and per node its edges, each a polyline
/// to another node (the corners between, then the node).
struct Graph {
  struct Edge {
    int to = 0;
    std::vector<P2> via;  // Corners, then the target node.
  };
  std::vector<P2> nodes;
  std::vector<std::vector<Edge>> edges;
  int add(P2 p) {
    nodes.push_back(p);
    edges.emplace_back();
    return static_cast<int>(nodes.size()) - 1;
  }
  void join(int a, int b, std::vector<P2> corners) {
    std::vector<P2> there = corners, back(corners.rbegin(), corners.rend());
    there.push_back(nodes[static_cast<std::size_t>(b)]);
    back.push_back(nodes[static_cast<std::size_t>(a)]);
    edges[static_cast<std::size_t>(a)].push_back({b, std::move(there)});
    edges[static_cast<std::size_t>(b)].push_back({a, std::move(back)});
  }
};

/// The level being built: its rooms, and the objects added so far.
struct Builder {
  Builder(int n, SceneDesc& scene) : rooms(n), d(scene) {}
  int rooms = 0;
  std::vector<Room> room;  // Row-major: rz * rooms + rx.
  SceneDesc& d;
  ObjectId id = 1;
  Graph floor[2];
  Room& at(int rx, int rz) { return room[static_cast<std::size_t>(rz * rooms + rx)]; }
  void box(Vec3 lo, Vec3 hi) {
    if (hi.x > lo.x && hi.y > lo.y && hi.z > lo.z) d.objects.push_back(box_between(id++, lo, hi));
  }
  double width() const { return rooms * kPitchX + kWall; }
  double depth() const { return (rooms - 1) * kPitchZ + kPitchX + kWall; }
  double corridor_z(int rz) const { return rz * kPitchZ + kPitchX + kWall + 0.5 * kCorridor; }  // Centre line.
};

/// A wall `kWall` thick from s0 to s1 along axis `along` (0: x, 2: z), its
/// near face at `c` on the other axis, from the floor to the roof, with its
/// doorways cut out: the wall is split where a doorway starts or ends, and
/// each piece keeps the heights no doorway opens.
void wall(Builder& b, int along, double s0, double s1, double c, std::vector<Door> doors) {
  std::vector<double> cuts = {s0, s1};
  for (const Door& door : doors) {
    cuts.push_back(door.at - kDoorHalf);
    cuts.push_back(door.at + kDoorHalf);
  }
  std::sort(cuts.begin(), cuts.end());
  for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
    const double a = cuts[i], e = cuts[i + 1];
    std::vector<std::pair<double, double>> open;  // Heights open here.
    for (const Door& door : doors)
      if (door.at - kDoorHalf <= a && e <= door.at + kDoorHalf) open.push_back({door.y0, door.y0 + kDoorHigh});
    std::sort(open.begin(), open.end());
    double y = 0.0;
    auto piece = [&](double y0, double y1) {
      if (along == 0) b.box(Vec3(a, y0, c), Vec3(e, y1, c + kWall));
      else b.box(Vec3(c, y0, a), Vec3(c + kWall, y1, e));
    };
    for (const auto& [o0, o1] : open) {
      piece(y, o0);
      y = std::max(y, o1);
    }
    piece(y, kRoof);
  }
}

/// Which rooms have an upper floor: about half, at least two.
void choose_rooms(Builder& b, Rng& rng) {
  int upper = 0;
  for (int rz = 0; rz < b.rooms; ++rz)
    for (int rx = 0; rx < b.rooms; ++rx) {
      Room r;
      r.rx = rx;
      r.rz = rz;
      r.x0 = rx * kPitchX + kWall;
      r.z0 = rz * kPitchZ + kWall;
      r.upper = rng.chance(0.5);
      upper += r.upper ? 1 : 0;
      b.room.push_back(r);
    }
  for (std::size_t i = 0; upper < 2 && i < b.room.size(); ++i)
    if (!b.room[i].upper) {
      b.room[i].upper = true;
      ++upper;
    }
}

/// A doorway's centre along its wall, on the 16-unit lattice, within
/// [lo, hi] of the room's inside.
double door_at(Rng& rng, double origin, int lo, int hi) {
  return origin + 16.0 * rng.uniform_int(lo / 16, hi / 16);
}

/// The walls along x (north and south of each row) with their doorways to
/// the corridors, and the corridors' nodes on each storey.
void walls_along_x(Builder& b, Rng& rng, std::vector<std::vector<int>> corridor_nodes[2]) {
  const int n = b.rooms;
  for (int k = 0; k < n; ++k) {  // Row k: south wall at k * pitch, north at + 512.
    for (int side = 0; side < 2; ++side) {
      const double c = k * kPitchZ + side * kPitchX;
      const int corridor = side == 0 ? k - 1 : k;  // Beyond this wall; -1 or n - 1: outside.
      const bool outer = corridor < 0 || corridor >= n - 1;
      for (int rx = 0; rx < n; ++rx) {
        Room& r = b.at(rx, k);
        // Each room's stretch ends where the next one's starts (no overlap).
        const double s0 = rx * kPitchX, s1 = s0 + kPitchX + (rx + 1 == n ? kWall : 0.0);
        std::vector<Door> doors;
        if (!outer) {
          for (int f = 0; f < (r.upper ? 2 : 1); ++f) {
            const Door door{door_at(rng, r.x0, 176, 320), f * kStorey};
            doors.push_back(door);
            Graph& g = b.floor[f];
            const P2 centre = r.centre();
            const int room_node = static_cast<int>(&r - b.room.data());  // Node i: room i.
            const int hall = g.add({door.at, b.corridor_z(corridor)});
            corridor_nodes[f][static_cast<std::size_t>(corridor)].push_back(hall);
            g.join(room_node, hall, {{door.at, centre.z}});
          }
        }
        wall(b, 0, s0, s1, c, doors);
      }
    }
  }
}

/// The walls along z (between the rooms of a row, and the outer ones), with
/// doorways between rooms; the corridors' end walls.
void walls_along_z(Builder& b, Rng& rng) {
  const int n = b.rooms;
  for (int rz = 0; rz < n; ++rz)
    for (int k = 0; k <= n; ++k) {
      const double c = k * kPitchX;
      const double s0 = rz * kPitchZ + kWall, s1 = s0 + kInside;
      std::vector<Door> doors;
      if (k > 0 && k < n) {
        Room& west = b.at(k - 1, rz);
        Room& east = b.at(k, rz);
        const int floors = west.upper && east.upper ? 2 : 1;
        for (int f = 0; f < floors; ++f) {
          const Door door{door_at(rng, west.z0, 400, 448), f * kStorey};
          doors.push_back(door);
          const int a = static_cast<int>(&west - b.room.data()), e = static_cast<int>(&east - b.room.data());
          b.floor[f].join(a, e, {{west.centre().x, door.at}, {east.centre().x, door.at}});
        }
      }
      wall(b, 2, s0, s1, c, doors);
    }
  // The corridors' ends: the outer walls along z, across each corridor.
  for (int rz = 0; rz + 1 < n; ++rz) {
    const double z0 = rz * kPitchZ + kPitchX + kWall, z1 = z0 + kCorridor;
    wall(b, 2, z0, z1, 0.0, {});
    wall(b, 2, z0, z1, n * kPitchX, {});
  }
}

/// Floors and roof, the upper floors with their stair holes, the stairs,
/// the corridors' walkways and the halls' pillars.
void slabs_stairs_pillars(Builder& b) {
  const double w = b.width(), dz = b.depth();
  b.box(Vec3(0.0, -kWall, 0.0), Vec3(w, 0.0, dz));     // Ground.
  b.box(Vec3(0.0, kRoof, 0.0), Vec3(w, kRoof + kWall, dz));  // Roof.
  const double y0 = kStorey - kWall, y1 = kStorey;
  for (int rz = 0; rz + 1 < b.rooms; ++rz) {
    const double z0 = rz * kPitchZ + kPitchX + kWall;
    b.box(Vec3(kWall, y0, z0), Vec3(b.rooms * kPitchX, y1, z0 + kCorridor));  // Walkway.
  }
  for (const Room& r : b.room) {
    const double x0 = r.x0, z0 = r.z0, x1 = x0 + kInside, z1 = z0 + kInside;
    if (r.upper) {
      const double hole_z1 = z0 + kStairZ0 + kSteps * 16.0;
      b.box(Vec3(x0 + kStairX, y0, z0), Vec3(x1, y1, z1));
      b.box(Vec3(x0, y0, z0), Vec3(x0 + kStairX, y1, z0 + kStairZ0));
      b.box(Vec3(x0, y0, hole_z1), Vec3(x0 + kStairX, y1, z1));
      for (int s = 0; s < kSteps; ++s)
        b.box(Vec3(x0, 0.0, z0 + kStairZ0 + 16.0 * s), Vec3(x0 + kStairX, 16.0 * (s + 1), z0 + kStairZ0 + 16.0 * (s + 1)));
    } else {
      for (const P2 p : {P2{96, 96}, P2{400, 96}, P2{96, 304}, P2{400, 304}})
        b.box(Vec3(x0 + p.x - kPillarHalf, 0.0, z0 + p.z - kPillarHalf),
              Vec3(x0 + p.x + kPillarHalf, kRoof, z0 + p.z + kPillarHalf));
    }
  }
}

/// Joins each corridor's nodes on each storey in order along it.
void join_corridors(Builder& b, std::vector<std::vector<int>> corridor_nodes[2]) {
  for (int f = 0; f < 2; ++f)
    for (std::vector<int>& nodes : corridor_nodes[f]) {
      Graph& g = b.floor[f];
      std::sort(nodes.begin(), nodes.end(), [&](int a, int e) {
        return g.nodes[static_cast<std::size_t>(a)].x < g.nodes[static_cast<std::size_t>(e)].x;
      });
      for (std::size_t i = 0; i + 1 < nodes.size(); ++i) g.join(nodes[i], nodes[i + 1], {});
    }
}

/// A walk: a random route through `g` from node `start`, at least `length`
/// long, as a polyline; never straight back unless there is no other way.
std::vector<P2> route(const Graph& g, int start, double length, Rng& rng) {
  std::vector<P2> path = {g.nodes[static_cast<std::size_t>(start)]};
  double walked = 0.0;
  int at = start, from = -1;
  while (walked < length) {
    const auto& out = g.edges[static_cast<std::size_t>(at)];
    if (out.empty()) break;  // A lone node: the walker stands.
    std::vector<std::size_t> choice;
    for (std::size_t i = 0; i < out.size(); ++i)
      if (out[i].to != from) choice.push_back(i);
    const auto& e = choice.empty() ? out[0] : out[choice[static_cast<std::size_t>(rng.uniform_int(0, static_cast<int>(choice.size()) - 1))]];
    for (const P2 p : e.via) {
      walked += std::hypot(p.x - path.back().x, p.z - path.back().z);
      path.push_back(p);
    }
    from = at;
    at = e.to;
  }
  return path;
}

/// A point `s` units along a polyline (its end beyond), and the heading of
/// the segment it lies on (radians about +y, 0 along +x).
struct Walker {
  std::vector<P2> path;
  std::vector<double> at;  // Arc length at each point.
  explicit Walker(std::vector<P2> p) : path(std::move(p)) {
    at.push_back(0.0);
    for (std::size_t i = 1; i < path.size(); ++i)
      at.push_back(at.back() + std::hypot(path[i].x - path[i - 1].x, path[i].z - path[i - 1].z));
  }
  P2 point(double s, double* heading) const {
    // The first point at or beyond s (the segment ending there holds it).
    const auto it = std::lower_bound(at.begin() + 1, at.end(), s);
    std::size_t i = static_cast<std::size_t>(it - at.begin());
    if (i >= path.size()) {
      if (heading && path.size() > 1) *heading = segment_heading(path.size() - 1);
      return path.back();
    }
    const double len = at[i] - at[i - 1];
    const double u = len > 0.0 ? std::clamp((s - at[i - 1]) / len, 0.0, 1.0) : 0.0;
    if (heading) *heading = segment_heading(i);
    return {path[i - 1].x + u * (path[i].x - path[i - 1].x), path[i - 1].z + u * (path[i].z - path[i - 1].z)};
  }
  double segment_heading(std::size_t i) const {
    return std::atan2(path[i].z - path[i - 1].z, path[i].x - path[i - 1].x);
  }
};

/// The first-person camera at time t on its walk: looking where it goes,
/// swaying, and every 4 s turning to look back for half a second.
Camera walk_camera(const Walker& walk, double t) {
  double heading = 0.0;
  const P2 p = walk.point(kRun * (1.0 - 1e-9) * t, &heading);
  const double phase = std::fmod(t, 4.0);
  const double back = phase > 2.0 && phase < 2.5 ? std::numbers::pi * std::sin(std::numbers::pi * (phase - 2.0) / 0.5)
                                                 : 0.0;
  const double yaw = heading + 0.5 * std::sin(2.0 * std::numbers::pi * t / 2.3) + back;
  const double pitch = 0.08 * std::sin(2.0 * std::numbers::pi * t / 3.1);
  Camera c;
  c.eye = Vec3(p.x, kEye, p.z);
  c.dir = Vec3(std::cos(pitch) * std::cos(yaw), std::sin(pitch), std::cos(pitch) * std::sin(yaw));
  c.up = Vec3(0.0, 1.0, 0.0);
  c.fov_y_deg = 73.74;  // 90 degrees across at 4:3, Quake's default.
  c.aspect = 16.0 / 9.0;
  c.near = 4.0;
  c.far = 8192.0;
  return c;
}

}  // namespace

ArenaLevel make_arena(int rooms, int players, int frames, std::uint64_t seed) {
  ArenaLevel out;
  Builder b(std::max(2, rooms), out.scene);
  Rng rng(seed);
  choose_rooms(b, rng);
  for (Graph& g : b.floor)
    for (const Room& r : b.room) g.add(r.centre());  // Node i: room i (floor 1's halls have no edges).
  std::vector<std::vector<int>> corridor_nodes[2];
  for (auto& c : corridor_nodes) c.resize(static_cast<std::size_t>(b.rooms - 1));
  walls_along_x(b, rng, corridor_nodes);
  walls_along_z(b, rng);
  join_corridors(b, corridor_nodes);
  slabs_stairs_pillars(b);
  SceneDesc& d = out.scene;
  d.bounds_min = Vec3(0.0, -kWall, 0.0);
  d.bounds_max = Vec3(b.width(), kRoof + kWall, b.depth());
  d.grid = glm::ivec3(static_cast<int>(b.width() / 16.0), static_cast<int>((kRoof + 2.0 * kWall) / 16.0),
                      static_cast<int>(b.depth() / 16.0));

  // Players: even ones on floor 0, odd ones on floor 1 (where it has
  // rooms), each starting at a random room or corridor point.
  const double seconds = frames / 60.0;
  std::vector<Walker> walks;
  std::vector<double> level;
  for (int i = 0; i < std::max(0, players); ++i) {
    const int f = i % 2;
    const Graph& g = b.floor[f];
    int start = 0;
    do start = rng.uniform_int(0, static_cast<int>(g.nodes.size()) - 1);
    while (g.edges[static_cast<std::size_t>(start)].empty());
    walks.emplace_back(route(g, start, kRun * seconds + 1.0, rng));
    level.push_back(f * kStorey + kPlayerHalf.y);
    const P2 p = walks.back().point(0.0, nullptr);
    ObjectDesc o = box_around(b.id++, Vec3(p.x, level.back(), p.z), kPlayerHalf);
    o.dynamic = true;
    o.max_speed = kRun;
    d.objects.push_back(o);
  }
  const ObjectId first_player = b.id - static_cast<ObjectId>(walks.size());
  const Walker camera(route(b.floor[0], rng.uniform_int(0, b.rooms * b.rooms - 1), kRun * seconds + 1.0, rng));
  for (int i = 0; i < std::max(0, frames); ++i) {
    FrameInput f;
    f.t = i / 60.0;
    f.line = i + 1;
    f.camera = walk_camera(camera, f.t);
    for (std::size_t k = 0; k < walks.size(); ++k) {
      const P2 p = walks[k].point(kRun * (1.0 - 1e-9) * f.t, nullptr);
      f.moves.push_back(Move{first_player + static_cast<ObjectId>(k), Vec3(p.x, level[k], p.z)});
    }
    out.frames.push_back(std::move(f));
  }
  return out;
}

}  // namespace voxvis
