#!/usr/bin/env python3
"""Checks that server/ calls one way: every file of server/src/<layer>/
includes only files of its own layer or of layers beneath it (by their
layer-qualified path), no include cycle exists among the server's files, and
the public header (server/include) includes nothing private.

  check_layers.py SERVER_DIR   check a tree; exit 1 naming every violation
  check_layers.py --self-test  check that the checker finds an upward
                               include, a bare include and a cycle
"""
import os
import re
import sys
import tempfile

LAYERS = ["wire", "scenes", "serving", "rpc", "process"]  # Beneath to above.
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def files_of(root):
    for top, _, names in os.walk(root):
        for n in sorted(names):
            if n.endswith((".h", ".cpp")):
                yield os.path.join(top, n)


def check(server):
    src = os.path.join(server, "src")
    problems = []
    private = {}  # Layer-qualified path -> file.
    for path in files_of(src):
        private[os.path.relpath(path, src)] = path
    bare = {os.path.basename(k): k for k in private}
    edges = {}
    for rel, path in private.items():
        layer = rel.split(os.sep)[0]
        if layer not in LAYERS:
            problems.append(f"{rel}: folder '{layer}' is not one of the layers {LAYERS}")
            continue
        edges[rel] = []
        for inc in INCLUDE.findall(open(path, encoding="utf-8").read()):
            if inc in private:
                target = inc.split("/")[0]
                if LAYERS.index(target) > LAYERS.index(layer):
                    problems.append(f"{rel}: includes {inc}, a layer above ({target} over {layer})")
                edges[rel].append(inc)
            elif inc in bare:
                problems.append(f"{rel}: includes \"{inc}\" without its layer (write \"{bare[inc]}\")")
            elif inc == "voxvis/server/server.h" and layer != "process":
                problems.append(f"{rel}: includes the public header from below the process layer")
    for path in files_of(os.path.join(server, "include")):
        for inc in INCLUDE.findall(open(path, encoding="utf-8").read()):
            if inc in private or inc in bare:
                problems.append(f"{os.path.relpath(path, server)}: the public header includes private {inc}")
    problems += cycles(edges)
    return problems


def cycles(edges):
    found, state, stack = [], {}, []

    def visit(n):
        state[n] = 1
        stack.append(n)
        for m in edges.get(n, []):
            if state.get(m) == 1:
                found.append("include cycle: " + " -> ".join(stack[stack.index(m):] + [m]))
            elif m not in state:
                visit(m)
        stack.pop()
        state[n] = 2

    for n in sorted(edges):
        if n not in state:
            visit(n)
    return found


def self_test():
    with tempfile.TemporaryDirectory() as d:
        def put(rel, text):
            os.makedirs(os.path.dirname(os.path.join(d, rel)), exist_ok=True)
            open(os.path.join(d, rel), "w").write(text)
        put("src/wire/a.h", '#include "wire/b.h"\n')
        put("src/wire/b.h", '#include "wire/a.h"\n')
        put("src/scenes/c.h", '#include "rpc/d.h"\n#include "a.h"\n')
        put("src/rpc/d.h", '// Nothing.\n')
        put("include/voxvis/server/server.h", '#include "rpc/d.h"\n')
        got = check(d)
        want = ["a layer above (rpc over scenes)", 'includes "a.h" without its layer',
                "public header includes private rpc/d.h", "include cycle: wire/a.h -> wire/b.h -> wire/a.h"]
        missed = [w for w in want if not any(w in p for p in got)]
        if missed or len(got) != len(want):
            print("self-test failed; found:\n  " + "\n  ".join(got) + "\nmissed: " + ", ".join(missed))
            return 1
    print("self-test: every planted violation found")
    return 0


def main():
    if sys.argv[1:] == ["--self-test"]:
        return self_test()
    if len(sys.argv) != 2:
        print(__doc__)
        return 2
    problems = check(sys.argv[1])
    for p in problems:
        print(p)
    if not problems:
        print(f"server layers: {', '.join(LAYERS)} (beneath to above); every include points down or across, no cycle")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
