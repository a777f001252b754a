#!/usr/bin/env bash
# make.sh [OUT_DIR] — the FZK house walk (docs/importing.md, "Example: a
# walk through the FZK house"): the house of Debian's assimp-testmodels
# (IFC/AC14-FZK-Haus.ifc, modelled by KIT/IAI) and eight people, boxes of
# 0.5 x 1.7 x 0.3 m written here as an OBJ file, imported into one scene
# with the people dynamic; a camera walks at eye height from the garden
# through the front door, along the hall and out through the terrace door
# while the people wander in their rooms; then `voxvis verify` on the ray
# caster (zero misses expected) and, unless SKIP_REPORT=1, `voxvis report`.
#
# Environment: VOXVIS (default build/voxvis), MODELS (default
# /usr/share/assimp/models), FRAMES (default 600, at 60 per second).
set -euo pipefail
cd "$(dirname "$0")/../.."
out="${1:-build/fzk-house}"
cli="${VOXVIS:-build/voxvis}"
models="${MODELS:-/usr/share/assimp/models}"
frames="${FRAMES:-600}"
house="$models/IFC/AC14-FZK-Haus.ifc"
if ! [ -f "$house" ]; then
  echo "make.sh: error: $house not found (Debian package assimp-testmodels)" >&2
  exit 2
fi
mkdir -p "$out"

# The ground floor's rooms (x0 x1 z0 z1, metres; the house spans x 0..12,
# z -10..0, y up, the ground floor at y 0..2.5), two people in each of four.
rooms=(
  "0.8 3.3 -9.2 -6.5"
  "4.5 7.0 -9.2 -6.5"
  "8.1 11.2 -9.2 -4.8"
  "0.8 6.9 -3.6 -0.6"
)

# people.obj: Person1..Person8, each a box standing on the floor at its
# start (the middle of its room's left or right half).
awk -v rooms="${rooms[*]}" 'BEGIN {
  n = split(rooms, r, " ")
  for (k = 0; k < 8; ++k) {
    i = int(k / 2) * 4
    x0 = r[i + 1]; x1 = r[i + 2]; z0 = r[i + 3]; z1 = r[i + 4]
    x = x0 + (x1 - x0) * (k % 2 == 0 ? 0.3 : 0.7); z = (z0 + z1) / 2
    printf "o Person%d\n", k + 1
    for (iy = 0; iy < 2; ++iy) for (ix = 0; ix < 2; ++ix) for (iz = 0; iz < 2; ++iz)
      printf "v %.3f %.3f %.3f\n", x + (ix ? 0.25 : -0.25), iy ? 1.7 : 0.0, z + (iz ? 0.15 : -0.15)
    b = k * 8 + 1
    printf "f %d %d %d %d\nf %d %d %d %d\n", b, b + 2, b + 3, b + 1, b + 4, b + 5, b + 7, b + 6
    printf "f %d %d %d %d\nf %d %d %d %d\n", b, b + 1, b + 5, b + 4, b + 2, b + 6, b + 7, b + 3
    printf "f %d %d %d %d\nf %d %d %d %d\n", b, b + 4, b + 6, b + 2, b + 1, b + 3, b + 7, b + 5
  }
}' >"$out/people.obj"

"$cli" import "$house" "$out/people.obj" --scene-out "$out/house.json" \
  --dynamic Person1 Person2 Person3 Person4 Person5 Person6 Person7 Person8 --max-speed 1.5

# The people's ids, from the names table (each object's "id" line comes
# just before its "name" line).
ids=$(grep -B1 '"name": "Person[1-8]"' "$out/house.names.json" | sed -n 's/.*"id": \([0-9]*\).*/\1/p' | tr '\n' ' ')
if [ "$(echo $ids | wc -w)" -ne 8 ]; then
  echo "make.sh: error: the names table does not name Person1..Person8" >&2
  exit 1
fi

# The walk: from the garden (-2.5, -5) east through the front door (x 0.2)
# along the hall to (6.2, -5), a turn south, into the living room and out
# through the terrace door (x 5 to 7 at z 0) to (6.2, 2.5); eye height 1.6.
# The people wander in their rooms at 1 m/s, turning now and then,
# bouncing off the room's walls; a move gives the displacement from the
# start (an OBJ object's centre is the model origin).
awk -v n="$frames" -v rooms="${rooms[*]}" -v ids="$ids" 'BEGIN {
  split(rooms, r, " "); split(ids, id, " ")
  srand(7)
  for (k = 0; k < 8; ++k) {
    i = int(k / 2) * 4
    x0[k] = r[i + 1] + 0.3; x1[k] = r[i + 2] - 0.3; z0[k] = r[i + 3] + 0.2; z1[k] = r[i + 4] - 0.2
    sx[k] = r[i + 1] + (r[i + 2] - r[i + 1]) * (k % 2 == 0 ? 0.3 : 0.7); sz[k] = (r[i + 3] + r[i + 4]) / 2
    px[k] = sx[k]; pz[k] = sz[k]; a[k] = 6.2831853 * rand()
  }
  la = 9.0; lb = 7.5; total = la + lb
  for (f = 0; f < n; ++f) {
    t = f / 60.0
    s = total * f / (n > 1 ? n - 1 : 1)
    if (s <= la) { ex = -2.5 + s; ez = -5.0 } else { ex = 6.5 - 0.3 * (s - la) / lb; ez = -5.0 + (s - la) }
    # Look ahead, turning over the metre around the corner.
    w = (s - (la - 1.0)) / 2.0; if (w < 0) w = 0; if (w > 1) w = 1
    dx = 1 - w; dz = w
    printf "{\"t\": %.6f, \"eye\": [%.4f, 1.6, %.4f], \"dir\": [%.4f, -0.05, %.4f], \"up\": [0, 1, 0], ", t, ex, ez, dx, dz
    printf "\"fov_y_deg\": 70, \"aspect\": 1.7778, \"near\": 0.05, \"far\": 100"
    if (f > 0) {
      printf ", \"moves\": ["
      for (k = 0; k < 8; ++k) {
        if (rand() < 0.02) a[k] += 3.1415927 * (rand() - 0.5)
        nx = px[k] + cos(a[k]) / 60.0; nz = pz[k] + sin(a[k]) / 60.0
        if (nx < x0[k] || nx > x1[k]) { a[k] = 3.1415927 - a[k]; nx = px[k] }
        if (nz < z0[k] || nz > z1[k]) { a[k] = -a[k]; nz = pz[k] }
        px[k] = nx; pz[k] = nz
        printf "%s{\"id\": %d, \"center\": [%.5f, 0, %.5f]}", k ? ", " : "", id[k + 1], px[k] - sx[k], pz[k] - sz[k]
      }
      printf "]"
    }
    printf "}\n"
  }
}' >"$out/walk.jsonl"

"$cli" replay --scene "$out/house.json" --frames "$out/walk.jsonl" --out "$out/pvs.jsonl"
"$cli" verify --scene "$out/house.json" --frames "$out/walk.jsonl" --pvs "$out/pvs.jsonl" --reference raycast \
  --resolution 640x360 --out "$out/verify.jsonl"
if [ "${SKIP_REPORT:-0}" != 1 ]; then
  "$cli" report --scene "$out/house.json" --frames "$out/walk.jsonl" --out "$out/report"
fi
