#!/usr/bin/env python3
"""A game backend's Tick stream, in Python: a recording replayed as ticks.

Tick k carries line k's time and moves, and one camera per viewer: viewer v
walks the recording from its own start (line v*n/N), as `voxvis tick` does.
Each viewer's answers are written as the lines `voxvis replay` writes.
With --ping-ms, each viewer's camera becomes a region chosen from its round
trip (region.py; docs/server.md, "Hiding players over a network").
See README.md: the stubs are generated from proto/voxvis/v1/voxvis.proto.
"""
import argparse
import asyncio
import json
import math
import os
import sys
import time

try:
    import grpc
    from voxvis.v1 import voxvis_pb2 as pb
    from voxvis.v1 import voxvis_pb2_grpc as pb_grpc
except ModuleNotFoundError as e:
    print(f"tick_client: error: cannot import {e.name}: "
          + ("install python3-grpcio and python3-protobuf (Debian)" if e.name.split(".")[0] in ("grpc", "google")
             else "generate the stubs and put their directory on PYTHONPATH (README.md)"), file=sys.stderr)
    sys.exit(2)

import idset
import region

# Exit status, as the voxvis CLI's: 2 bad input or a refused call, 1 the
# server broke the contract.
EXIT_ERROR, EXIT_PROTOCOL = 2, 1


class Failure(Exception):
    def __init__(self, message, status=EXIT_ERROR):
        super().__init__(message)
        self.status = status


# --- Input ------------------------------------------------------------------

KEYS = ("t", "eye", "dir", "up", "fov_y_deg", "aspect", "near", "far")


def shape_error(frame):
    """What is wrong with the shape of a frames line, or None. Only its shape
    is checked here; the server checks the values and names the field."""
    def number(x):
        return isinstance(x, (int, float)) and not isinstance(x, bool)
    def vector(x):
        return isinstance(x, list) and len(x) == 3 and all(map(number, x))
    if not isinstance(frame, dict):
        return "not a JSON object"
    for key in KEYS:
        if key not in frame:
            return f"missing key '{key}'"
        if not (vector if key in ("eye", "dir", "up") else number)(frame[key]):
            return f"{key}: expected {'[x, y, z]' if key in ('eye', 'dir', 'up') else 'a number'}"
    if "eye_extent" in frame and not vector(frame["eye_extent"]):
        return "eye_extent: expected [hx, hy, hz]"
    if not isinstance(frame.get("omnidirectional", False), bool):
        return "omnidirectional: expected true or false"
    if not number(frame.get("horizon_s", 0)):
        return "horizon_s: expected a number"
    if not isinstance(frame.get("moves", []), list):
        return "moves: expected an array"
    for i, m in enumerate(frame.get("moves", [])):
        if not (isinstance(m, dict) and isinstance(m.get("id"), int) and vector(m.get("center"))):
            return f"moves[{i}]: expected {{\"id\": <integer>, \"center\": [x, y, z]}}"
        rotation = m.get("rotation", [1, 0, 0, 0])
        if not (isinstance(rotation, list) and len(rotation) == 4 and all(map(number, rotation))):
            return f"moves[{i}].rotation: expected [w, x, y, z]"
    return None


def read_frames(path):
    """The frames file (docs/formats.md) as [(line number, dict)]."""
    def no_constant(name):
        raise ValueError(f"{name} is not a number JSON allows")
    frames = []
    try:
        with open(path, encoding="utf-8-sig") as f:
            for number, line in enumerate(f, 1):
                if not line.strip():
                    continue
                try:
                    frame = json.loads(line, parse_constant=no_constant)
                except ValueError as e:
                    raise Failure(f"{path}:{number}: not JSON: {e}")
                if error := shape_error(frame):
                    raise Failure(f"{path}:{number}: {error}")
                frames.append((number, frame))
    except OSError as e:
        raise Failure(f"{path}: cannot read: {e.strerror}")
    if not frames:
        raise Failure(f"{path}: no frames in the file (tick needs at least one)")
    return frames


def vec3(v):
    return pb.Vec3(x=v[0], y=v[1], z=v[2])


def move(m):
    """A frames-file move; a mesh's rotation [w, x, y, z] goes with it (the
    server checks it is a unit quaternion and that the object is a mesh)."""
    out = pb.Move(id=m["id"], center=vec3(m["center"]))
    if "rotation" in m:
        w, x, y, z = m["rotation"]
        out.rotation.CopyFrom(pb.Quat(w=w, x=x, y=y, z=z))
    return out


def camera(f, player=None):
    """A frames-file camera, with its region fields; `player`, when given, is
    (eye_extent, horizon_s) from region.region_for, set over them with every
    direction counting."""
    c = pb.Camera(eye=vec3(f["eye"]), dir=vec3(f["dir"]), up=vec3(f["up"]), fov_y_deg=f["fov_y_deg"],
                  aspect=f["aspect"], near=f["near"], far=f["far"],
                  omnidirectional=f.get("omnidirectional", False), horizon_s=f.get("horizon_s", 0.0))
    if "eye_extent" in f:
        c.eye_extent.CopyFrom(vec3(f["eye_extent"]))
    if player is not None:
        extent, horizon = player
        c.eye_extent.CopyFrom(vec3(extent))
        c.omnidirectional = True
        c.horizon_s = horizon
    return c


def read_token(path):
    """The first line of a token file that is neither blank nor a comment."""
    try:
        with open(path, encoding="ascii") as f:
            lines = [line.strip() for line in f]
    except OSError as e:
        raise Failure(f"{path}: cannot read the token file: {e.strerror}")
    except UnicodeDecodeError:
        raise Failure(f"{path}: the token file is not ASCII text")
    for line in lines:
        if line and not line.startswith("#"):
            return line
    raise Failure(f"{path}: no token in the file")


# --- Output: the lines of `voxvis replay` (docs/formats.md, "Output file") ---

COUNTERS = ("voxels_visited", "shells", "objects_discretized", "tbvs_created", "tbvs_revealed",
            "tbvs_expired", "tbvs_active", "speed_violations", "outside_tested", "pvs_size")
BUFFER = ("ob_width", "ob_voxels_culled", "ob_objects_culled", "ob_occluders", "ob_pixels_written",
          "cells_visited", "cells_hidden", "cells_whole")


def result_line(frame, pvs, wake, s):
    def us(v):
        return f"{v if math.isfinite(v) else 0.0:.3f}"
    def ids(v):
        return "[" + ",".join(map(str, v)) + "]"
    fields = [f'"time_us":{us(s.time_us)}', f'"traverse_us":{us(s.traverse_us)}',
              f'"render_us":{us(s.render_us)}', f'"retest_us":{us(s.retest_us)}']
    fields += [f'"{name}":{getattr(s, name)}' for name in COUNTERS]
    fields += [f'"early_exit":{json.dumps(s.early_exit)}', f'"frustum_fallback":{json.dumps(s.frustum_fallback)}']
    if s.region:  # Only for a region camera.
        fields.append('"region":true')
    fields += [f'"front_voxels_culled":{s.front_voxels_culled}', f'"front_objects_culled":{s.front_objects_culled}']
    if s.ob_width > 0:  # Only with the occlusion buffer on.
        fields += [f'"{name}":{getattr(s, name)}' for name in BUFFER]
    return f'{{"frame":{frame},"pvs":{ids(pvs)},"wake":{ids(wake)},"stats":{{{",".join(fields)}}}}}\n'


def open_outputs(out, viewers):
    """One file a viewer: OUT itself for one (stdout without --out), else OUT/viewer-<v>.jsonl."""
    if viewers == 1:
        return [open(out, "w") if out else sys.stdout]
    os.makedirs(out, exist_ok=True)
    return [open(os.path.join(out, f"viewer-{v}.jsonl"), "w") for v in range(viewers)]


# --- Errors -------------------------------------------------------------------

def describe(error, args, where):
    """A failed call as one line: its status, its message and, for
    INVALID_ARGUMENT, the field the server names in the standard
    grpc-status-details-bin trailer (a google.rpc.Status holding a BadRequest;
    voxvis_pb2 has wire-compatible copies)."""
    code = error.code()
    if code == grpc.StatusCode.UNAVAILABLE:
        return f"cannot reach server at {args.server}: {error.details()}"
    text = f"server: {code.name}: {error.details()}"
    for key, value in error.trailing_metadata() or ():
        if key == "grpc-status-details-bin":
            for detail in pb.ErrorStatus.FromString(value).details:
                if detail.type_url.endswith("/google.rpc.BadRequest"):
                    bad = pb.BadRequest.FromString(detail.value)
                    text += "".join(f" [field {v.field}]" for v in bad.field_violations)
    # Errors about what was sent name the frames line it came from.
    if where and code in (grpc.StatusCode.INVALID_ARGUMENT, grpc.StatusCode.OUT_OF_RANGE,
                          grpc.StatusCode.FAILED_PRECONDITION, grpc.StatusCode.RESOURCE_EXHAUSTED):
        text = f"{where}: {text}"
    return text


# --- The Tick stream ----------------------------------------------------------

class ProtocolError(Exception):
    """The server answered something the contract does not allow."""


class TickSession:
    """The Tick stream, lock-step: tick() writes one tick and reads its
    answer. Keeps each viewer's PVS (the base of its deltas) and the scene's
    wake list. A failed call raises grpc.aio.AioRpcError (a grpc.RpcError)."""

    def __init__(self, stub, scene, delta, metadata):
        self.scene, self.first = scene, True
        self.encoding = pb.PVS_DELTA if delta else pb.PVS_FULL
        self.call = stub.Tick(metadata=metadata)
        self.pvs = {}                 # Viewer id -> its PVS, ascending.
        self.wake = idset.WakeList()  # The scene's: simulate these objects.
        self.forms = {"gaps": 0, "bits": 0, "empty": 0}

    async def tick(self, number, t, moves, cameras):
        """Sends tick `number` at time t with its moves (a simulation token)
        and {viewer id: camera}; returns [(viewer id, TickAnswer, PVS, wake)]
        in the cameras' order (PVS and wake None for a refused viewer)."""
        request = pb.TickRequest(tick=number, t=t, moves=moves)
        if self.first:  # The first request names the scene and the encoding.
            request.scene_id, request.encoding, self.first = self.scene, self.encoding, False
        for viewer, cam in cameras.items():
            request.viewers.add(viewer=viewer, camera=cam)
        await self.call.write(request)
        response = await self.call.read()
        if response is grpc.aio.EOF:
            raise ProtocolError(f"the stream ended without answering tick {number}")
        if response.tick != number or response.encoding != self.encoding or len(response.answers) != len(cameras):
            raise ProtocolError(f"tick {number} answered by tick {response.tick}, encoding {response.encoding}, "
                                f"{len(response.answers)} answers for {len(cameras)} viewers")
        out = []
        for i, (viewer, a) in enumerate(zip(cameras, response.answers)):
            try:
                if a.viewer != viewer:
                    raise ValueError(f"is for viewer {a.viewer}, asked for {viewer}")
                if a.HasField("error"):  # Refused alone; the others are answered.
                    out.append((viewer, a, None, None))
                    continue
                if self.encoding == pb.PVS_DELTA:
                    self.pvs[viewer] = idset.apply_delta(self.pvs.get(viewer, []), self.decode(a.removed),
                                                         self.decode(a.added))
                else:
                    self.pvs[viewer] = self.decode(a.pvs)
                out.append((viewer, a, self.pvs[viewer], self.decode(a.wake)))
            except ValueError as e:
                raise ProtocolError(f"tick {number}: answers[{i}]: {e}")
        if response.HasField("wake"):  # The scene's wake list changed.
            try:
                self.wake.apply(response.wake)
            except ValueError as e:
                raise ProtocolError(f"tick {number}: {e}")
        return out

    def decode(self, ids):
        self.forms[idset.form(ids)] += 1
        return idset.decode(ids)

    async def close(self):
        """Ends the stream; raises grpc.aio.AioRpcError when it did not end well."""
        await self.call.done_writing()
        if (extra := await self.call.read()) is not grpc.aio.EOF:
            raise ProtocolError(f"an answer to tick {extra.tick}, never sent")


async def run(args):
    frames = read_frames(args.frames)
    token_file = args.token_file or os.environ.get("VOXVIS_TOKEN_FILE")
    metadata = [("authorization", "Bearer " + read_token(token_file))] if token_file else []
    # gRPC's Python default of 4 MiB a message is short for many large PVSs.
    options = [("grpc.max_receive_message_length", 64 << 20), ("grpc.max_send_message_length", 64 << 20)]
    if args.tls_server_name:  # The name the certificate must hold, instead of the address's host.
        options.append(("grpc.ssl_target_name_override", args.tls_server_name))
    if args.tls_ca:
        with open(args.tls_ca, "rb") as f:
            credentials = grpc.ssl_channel_credentials(root_certificates=f.read())
        channel = grpc.aio.secure_channel(args.server, credentials, options)
    else:
        channel = grpc.aio.insecure_channel(args.server, options)
    outs = open_outputs(args.out, args.viewers)

    n, viewers = len(frames), args.viewers
    players = [None] * viewers
    if args.ping_ms:  # Each viewer's region from its round trip (the last ping repeats).
        for v in range(viewers):
            ping = args.ping_ms[min(v, len(args.ping_ms) - 1)]
            players[v] = region.region_for(ping / 1000, 1 / args.tick_hz, args.interp_ms / 1000, args.speed,
                                           args.vertical)
    start_line = [v * n // viewers for v in range(viewers)]  # Viewer v's first frame.
    start, pvs_total, line = time.monotonic(), 0, frames[0][0]
    try:
        async with channel:  # Closing the channel ends its calls.
            session = TickSession(pb_grpc.VisibilityStub(channel), args.scene, args.delta, metadata)
            for k, (line, frame) in enumerate(frames):
                moves = [move(m) for m in frame.get("moves", [])]
                cameras = {v: camera(frames[(start_line[v] + k) % n][1], players[v]) for v in range(viewers)}
                for viewer, answer, pvs, wake in await session.tick(k, frame["t"], moves, cameras):
                    if answer.HasField("error"):
                        raise Failure(f"{args.frames}:{frames[(start_line[viewer] + k) % n][0]}: "
                                      f"{answer.error.field}: {answer.error.description} (viewer {viewer})")
                    outs[viewer].write(result_line(k, pvs, wake, answer.stats))
                    pvs_total += len(pvs)
            await session.close()
    except grpc.RpcError as e:
        raise Failure(describe(e, args, f"{args.frames}:{line}"))
    except ProtocolError as e:
        raise Failure(f"protocol: {e}", EXIT_PROTOCOL)
    finally:
        for f in outs:
            f.flush()
            if f is not sys.stdout:
                f.close()

    if not args.quiet:
        forms = session.forms
        print(f"tick_client: {n} ticks of {viewers} viewers in {time.monotonic() - start:.2f} s; "
              f"mean PVS {pvs_total / (n * viewers):.1f} objects; id sets: {forms['gaps']} as gaps, "
              f"{forms['bits']} as bitsets, {forms['empty']} empty; "
              f"scene wake list {len(session.wake.ids)} objects", file=sys.stderr)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--server", default="127.0.0.1:50051", help="HOST:PORT (default %(default)s)")
    p.add_argument("--scene", required=True, help="scene id")
    p.add_argument("--frames", required=True, help="frames file F.jsonl (docs/formats.md)")
    p.add_argument("--viewers", type=int, default=1, help="viewers a tick (default 1)")
    p.add_argument("--delta", action="store_true", help="PVS_DELTA: answers carry changes, rebuilt here")
    p.add_argument("--out", help="output file (one viewer; default stdout) or directory (several)")
    p.add_argument("--token-file", help="file holding the bearer token; default $VOXVIS_TOKEN_FILE")
    p.add_argument("--tls-ca", help="PEM root certificates: TLS on")
    p.add_argument("--tls-server-name", help="name the server's certificate holds, if not the host of --server")
    p.add_argument("--ping-ms", type=lambda s: [float(x) for x in s.split(",")],
                   help="round trips PING[,PING...] in ms, one a viewer (the last repeats): each viewer's "
                        "camera becomes the region its round trip needs")
    p.add_argument("--tick-hz", type=float, default=64.0, help="with --ping-ms: ticks a second (default 64)")
    p.add_argument("--interp-ms", type=float, default=0.0, help="with --ping-ms: interpolation delay, ms")
    p.add_argument("--speed", type=float, default=320.0, help="with --ping-ms: players' top speed, units/s")
    p.add_argument("--vertical", type=float, default=0.0, help="with --ping-ms: eye's vertical reach, units")
    p.add_argument("-q", "--quiet", action="store_true", help="no summary on stderr")
    args = p.parse_args()
    if args.ping_ms is not None:
        if not args.tick_hz > 0 or args.tick_hz == float("inf"):
            p.error(f"--tick-hz: must be > 0, got {args.tick_hz}")
        try:
            region.region_for(min(args.ping_ms) / 1000, 1 / args.tick_hz, args.interp_ms / 1000, args.speed,
                              args.vertical)
            region.region_for(max(args.ping_ms) / 1000, 1 / args.tick_hz, args.interp_ms / 1000, args.speed,
                              args.vertical)
        except ValueError as e:
            p.error(f"--ping-ms/--interp-ms/--speed/--vertical: {e}")
    if args.viewers < 1 or args.viewers > 1024:
        p.error(f"--viewers: must be in [1, 1024], got {args.viewers}")
    if args.viewers > 1 and not args.out:
        p.error("--out: with --viewers above 1, name a directory for the viewers' files")
    try:
        asyncio.run(run(args))
    except Failure as e:
        prefix = "internal error" if e.status == EXIT_PROTOCOL else "error"
        print(f"tick_client: {prefix}: {e}", file=sys.stderr)
        return e.status
    except OSError as e:  # An output or certificate file.
        print(f"tick_client: error: {e.filename or 'output'}: {e.strerror}", file=sys.stderr)
        return EXIT_ERROR
    except KeyboardInterrupt:
        return 130
    return 0


if __name__ == "__main__":
    sys.exit(main())
