#!/usr/bin/python3
"""Checks the Kubernetes manifests of deploy/k8s/ against the API's schema.

    test_manifests.py DIR            every document of DIR/*.yaml; exit 1 naming each fault
    test_manifests.py --self-test DIR  breaks DIR's manifests in known ways; each must be caught

The schema is Debian's python3-kubernetes (22.6, generated from the
Kubernetes 1.22 OpenAPI document): its API modules say which kinds each
apiVersion serves, its models list every object's fields with their types,
and their constructors refuse a missing required field. Fields newer than
1.22 that the manifests use are added below from the Kubernetes API reference
(v1.27, where they are GA). On top of the schema, the rules the API server
enforces or that would break the manifests at run time: names, selectors
matching the template's labels, volumes and ports referred to by name,
$(VAR) references, quantities, Indexed Jobs, and voxvis's --shard/--fleet.
"""
import glob
import os
import re
import sys

import yaml
from kubernetes import client

API_DIR = os.path.join(os.path.dirname(client.__file__), "api")

# Kubernetes API reference v1.27: Probe.grpc (GRPCAction: port int32,
# required; service string). GA in 1.27, beta from 1.24.
EXTRA_FIELDS = {"V1Probe": {"grpc": "V1GRPCAction"}}
EXTRA_MODELS = {"V1GRPCAction": ({"port": "int", "service": "str"}, {"port"})}

DNS_LABEL = re.compile(r"^[a-z0-9]([-a-z0-9]{0,61}[a-z0-9])?$")
DNS_SUBDOMAIN = re.compile(r"^[a-z0-9]([-a-z0-9.]{0,251}[a-z0-9])?$")
ENV_NAME = re.compile(r"^[-._a-zA-Z][-._a-zA-Z0-9]*$")
PORT_NAME = re.compile(r"^(?=.{1,15}$)(?=.*[a-z])[a-z0-9]+(-[a-z0-9]+)*$")
QUANTITY = re.compile(r"^[+]?([0-9]+(\.[0-9]*)?|\.[0-9]+)([eE][+-]?[0-9]+|Ki|Mi|Gi|Ti|Pi|Ei|m|k|M|G|T|P|E)?$")
SUFFIX = {"": 1, "m": 1e-3, "k": 1e3, "M": 1e6, "G": 1e9, "T": 1e12, "P": 1e15, "E": 1e18,
          "Ki": 2**10, "Mi": 2**20, "Gi": 2**30, "Ti": 2**40, "Pi": 2**50, "Ei": 2**60}
WORKLOADS = ("Pod", "Deployment", "StatefulSet", "Job")


def served_kinds():
    """{apiVersion: {class name}} from the client's API modules."""
    served = {}
    for path in glob.glob(os.path.join(API_DIR, "*_api.py")):
        text = open(path, encoding="utf-8").read()
        m = re.search(r"'/apis?/((?:[a-z0-9.-]+/)?v[0-9a-z]+)/'", text)
        if m:
            served.setdefault(m.group(1), set()).update(re.findall(r"response_type='(V[0-9a-z]+\w*)'", text))
    return served


class Checker:
    def __init__(self):
        self.errors = []
        self.served = served_kinds()

    def err(self, where, message):
        self.errors.append(f"{where}: {message}")

    # --- the schema -------------------------------------------------------
    def typed(self, value, type_name, where):
        if type_name.startswith("list["):
            if not isinstance(value, list):
                return self.err(where, f"must be a list, got {type(value).__name__}")
            for i, item in enumerate(value):
                self.typed(item, type_name[5:-1], f"{where}[{i}]")
        elif type_name.startswith("dict("):
            if not isinstance(value, dict):
                return self.err(where, f"must be a map, got {type(value).__name__}")
            inner = type_name[5:-1].split(", ", 1)[1]
            for k, v in value.items():
                self.typed(v, inner, f"{where}.{k}")
        elif type_name == "str":
            if not isinstance(value, str):
                self.err(where, f"must be a string, got {value!r}")
        elif type_name == "int":
            if not isinstance(value, int) or isinstance(value, bool):
                self.err(where, f"must be an integer, got {value!r}")
        elif type_name == "bool":
            if not isinstance(value, bool):
                self.err(where, f"must be true or false, got {value!r}")
        elif type_name in ("object", "float", "datetime", "date"):
            pass  # int-or-string, quantities, free-form: checked by the rules below
        else:
            self.model(value, type_name, where)

    def model(self, value, name, where):
        if not isinstance(value, dict):
            return self.err(where, f"must be an object ({name}), got {value!r}")
        if name in EXTRA_MODELS:
            fields, required = EXTRA_MODELS[name]
            for r in sorted(required - value.keys()):
                self.err(where, f"{name}: required field '{r}' is missing")
            attrs = {k: k for k in fields}
        else:
            cls = getattr(client, name)
            fields = {cls.attribute_map[a]: t for a, t in cls.openapi_types.items()}
            fields.update(EXTRA_FIELDS.get(name, {}))
            attrs = {v: k for k, v in cls.attribute_map.items()}
            kwargs = {attrs[k]: v for k, v in value.items() if k in attrs}
            try:
                cls(**kwargs)
            except ValueError as e:  # a required field is missing
                self.err(where, f"{name}: {e}")
        for key, v in value.items():
            if key not in fields:
                self.err(f"{where}.{key}", f"no such field in {name}")
            else:
                self.typed(v, fields[key], f"{where}.{key}")

    # --- the rules beyond the schema ---------------------------------------
    def quantity(self, value, where):
        text = str(value)
        m = QUANTITY.match(text)
        if not m:
            self.err(where, f"'{text}' is not a Kubernetes quantity (e.g. 500m, 2, 512Mi)")
            return None
        number = text[:len(text) - len(m.group(3) or "")]
        suffix = m.group(3) or ""
        return float(text) if suffix[:1] in ("e", "E") else float(number) * SUFFIX[suffix]

    def pod_spec(self, spec, where, labels, claim_templates=(), kind="Pod"):
        volumes = {v.get("name") for v in spec.get("volumes", []) or []} | set(claim_templates)
        for v in spec.get("volumes", []) or []:
            claim = (v.get("persistentVolumeClaim") or {}).get("claimName")
            if claim and claim not in self.names.get("PersistentVolumeClaim", ()):
                self.err(f"{where}.volumes[{v.get('name')}]", f"claim '{claim}' is defined by no manifest here")
            cm = (v.get("configMap") or {}).get("name")
            if cm and cm not in self.names.get("ConfigMap", ()):
                self.err(f"{where}.volumes[{v.get('name')}]", f"ConfigMap '{cm}' is defined by no manifest here")
        if kind == "Job" and spec.get("restartPolicy") not in ("Never", "OnFailure"):
            self.err(f"{where}.restartPolicy", "a Job's pods need Never or OnFailure")
        ports_all = set()
        names = set()
        for i, c in enumerate(spec.get("containers", []) or []):
            cw = f"{where}.containers[{i}]"
            name = c.get("name", "")
            if not DNS_LABEL.match(name):
                self.err(f"{cw}.name", f"'{name}' is not a DNS-1123 label")
            if name in names:
                self.err(f"{cw}.name", f"'{name}' is used twice")
            names.add(name)
            if not c.get("image"):
                self.err(f"{cw}.image", "a container needs an image")
            env = set()
            for e in c.get("env", []) or []:
                if not ENV_NAME.match(str(e.get("name", ""))):
                    self.err(f"{cw}.env", f"'{e.get('name')}' is not a valid variable name")
                env.add(e.get("name"))
            for field in ("command", "args"):
                for arg in c.get(field, []) or []:
                    for ref in re.findall(r"(?<!\$)\$\(([-._a-zA-Z][-._a-zA-Z0-9]*)\)", str(arg)):
                        if ref not in env:
                            self.err(f"{cw}.{field}", f"$({ref}) names no env variable of the container (left unexpanded)")
            ports = {}
            for p in c.get("ports", []) or []:
                n = p.get("containerPort")
                if not isinstance(n, int) or not 1 <= n <= 65535:
                    self.err(f"{cw}.ports", f"containerPort {n!r} is not in 1..65535")
                if "name" in p:
                    if not PORT_NAME.match(str(p["name"])):
                        self.err(f"{cw}.ports", f"port name '{p['name']}' is not an IANA service name")
                    ports[p["name"]] = n
            ports_all |= set(ports) | set(ports.values())
            for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
                pr = c.get(probe)
                if not pr:
                    continue
                handlers = [h for h in ("exec", "httpGet", "tcpSocket", "grpc") if h in pr]
                if len(handlers) != 1:
                    self.err(f"{cw}.{probe}", f"needs exactly one handler, has {handlers or 'none'}")
                for h in handlers:
                    port = (pr[h] or {}).get("port") if h != "exec" else None
                    if port is not None and port not in ports and port not in ports.values():
                        self.err(f"{cw}.{probe}.{h}.port", f"{port!r} is none of the container's ports")
            for m in c.get("volumeMounts", []) or []:
                if m.get("name") not in volumes:
                    self.err(f"{cw}.volumeMounts", f"'{m.get('name')}' is no volume of the pod")
                if not str(m.get("mountPath", "")).startswith("/"):
                    self.err(f"{cw}.volumeMounts", f"mountPath '{m.get('mountPath')}' is not absolute")
            res = c.get("resources") or {}
            req = {k: self.quantity(v, f"{cw}.resources.requests.{k}") for k, v in (res.get("requests") or {}).items()}
            lim = {k: self.quantity(v, f"{cw}.resources.limits.{k}") for k, v in (res.get("limits") or {}).items()}
            for k in req.keys() & lim.keys():
                if req[k] is not None and lim[k] is not None and req[k] > lim[k]:
                    self.err(f"{cw}.resources", f"{k} request above its limit")
        port = (labels.get("annotations") or {}).get("prometheus.io/port")
        if port is not None and int(port) not in ports_all:
            self.err(f"{where}: prometheus.io/port", f"{port} is none of the containers' ports")
        return ports_all

    def selector(self, sel, labels, where):
        match = (sel or {}).get("matchLabels") or {}
        if not match and not (sel or {}).get("matchExpressions"):
            self.err(where, "an empty selector")
        for k, v in match.items():
            if labels.get(k) != v:
                self.err(where, f"{k}={v} does not match the template's labels {labels}")

    def fleet(self, doc, c, where):
        """voxvis's shard identity: --shard $(POD_NAME) from metadata.name,
        --fleet naming every replica in order."""
        args = []
        for a in (c.get("command") or []) + (c.get("args") or []):
            # --opt=value and --opt value alike.
            a = str(a)
            args.extend(a.split("=", 1) if a.startswith("--") and "=" in a else [a])
        if "--fleet" not in args:
            return
        names = args[args.index("--fleet") + 1].split(",")
        replicas = doc["spec"].get("replicas", 1)
        if not isinstance(replicas, int):
            return  # reported by the schema
        want = [f"{doc['metadata']['name']}-{i}" for i in range(replicas)]
        if names != want:
            self.err(f"{where}: --fleet", f"{','.join(names)} is not the StatefulSet's pods {','.join(want)}")
        shard = args[args.index("--shard") + 1] if "--shard" in args else None
        pod_name = [e for e in c.get("env", []) if e.get("name") == "POD_NAME"]
        if shard != "$(POD_NAME)" or not pod_name or \
                pod_name[0].get("valueFrom", {}).get("fieldRef", {}).get("fieldPath") != "metadata.name":
            self.err(f"{where}: --shard", "must be $(POD_NAME), POD_NAME from the downward API's metadata.name")

    def document(self, doc, where):
        if not isinstance(doc, dict):
            return self.err(where, "a document must be an object")
        api, kind = doc.get("apiVersion"), doc.get("kind")
        if api not in self.served:
            return self.err(where, f"apiVersion '{api}' is served by no API group")
        version = api.split("/")[-1]
        cls = version[0].upper() + version[1:] + str(kind)
        if cls not in self.served[api]:
            return self.err(where, f"kind '{kind}' is not served by {api}")
        self.model(doc, cls, where)
        meta = doc.get("metadata") or {}
        if not DNS_SUBDOMAIN.match(str(meta.get("name", ""))):
            self.err(f"{where}.metadata.name", f"'{meta.get('name')}' is not a DNS-1123 name")
        spec = doc.get("spec") or {}
        if kind == "Pod":
            self.pod_spec(spec, f"{where}.spec", meta, kind="Pod")
        elif kind in WORKLOADS:
            t = spec.get("template") or {}
            tl = (t.get("metadata") or {}).get("labels") or {}
            if kind != "Job" or "selector" in spec:
                self.selector(spec.get("selector"), tl, f"{where}.spec.selector")
            claims = [(c.get("metadata") or {}).get("name") for c in spec.get("volumeClaimTemplates", []) or []]
            self.pod_spec(t.get("spec") or {}, f"{where}.spec.template.spec", t.get("metadata") or {}, claims, kind)
            for i, c in enumerate((t.get("spec") or {}).get("containers", []) or []):
                if kind == "StatefulSet":
                    self.fleet(doc, c, f"{where}.spec.template.spec.containers[{i}]")
            if kind == "StatefulSet":
                svc = self.docs.get(("Service", spec.get("serviceName")))
                if not svc:
                    self.err(f"{where}.spec.serviceName", f"'{spec.get('serviceName')}' is no Service here")
                elif (svc.get("spec") or {}).get("clusterIP") != "None":
                    self.err(f"{where}.spec.serviceName", "the StatefulSet's Service must be headless (clusterIP: None)")
            if kind == "Job" and spec.get("completionMode") == "Indexed" and not spec.get("completions"):
                self.err(f"{where}.spec.completions", "an Indexed Job needs completions")
        elif kind in ("Service", "PodDisruptionBudget"):
            sel = spec.get("selector") or {}
            sel = sel.get("matchLabels", sel) if kind == "PodDisruptionBudget" else sel
            if not any(all(tl.get(k) == v for k, v in sel.items()) for tl in self.template_labels):
                self.err(f"{where}.spec.selector", f"{sel} selects no workload's pods here")
            if kind == "PodDisruptionBudget" and ("minAvailable" in spec) == ("maxUnavailable" in spec):
                self.err(f"{where}.spec", "needs exactly one of minAvailable and maxUnavailable")
            for i, p in enumerate(spec.get("ports", []) or []):
                if not isinstance(p.get("port"), int) or not 1 <= p["port"] <= 65535:
                    self.err(f"{where}.spec.ports[{i}].port", f"{p.get('port')!r} is not in 1..65535")

    def check(self, files):
        loaded = []
        for path in files:
            try:
                for i, doc in enumerate(yaml.safe_load_all(open(path, encoding="utf-8"))):
                    if doc is not None:
                        loaded.append((f"{os.path.basename(path)}#{i}", doc))
            except yaml.YAMLError as e:
                self.err(os.path.basename(path), f"not YAML: {e}")
        return self.check_documents(loaded)

    def check_documents(self, loaded):
        """loaded: [(where, document)]."""
        self.load(loaded)
        for where, doc in loaded:
            self.document(doc, f"{where} {doc.get('kind') if isinstance(doc, dict) else ''}")
        return loaded

    def load(self, loaded):
        """What the documents may refer to by name: Services, claims, ConfigMaps, pods' labels."""
        self.docs, self.names, self.template_labels = {}, {}, []
        for _, doc in loaded:
            if not isinstance(doc, dict):
                continue
            name = (doc.get("metadata") or {}).get("name")
            self.docs[(doc.get("kind"), name)] = doc
            self.names.setdefault(doc.get("kind"), set()).add(name)
            if doc.get("kind") == "Pod":
                self.template_labels.append((doc.get("metadata") or {}).get("labels") or {})
            elif doc.get("kind") in WORKLOADS:
                t = (doc.get("spec") or {}).get("template") or {}
                self.template_labels.append((t.get("metadata") or {}).get("labels") or {})
            for c in (doc.get("spec") or {}).get("volumeClaimTemplates", []) or []:
                self.names.setdefault("PersistentVolumeClaim", set()).add((c.get("metadata") or {}).get("name"))


def main(argv):
    if len(argv) == 3 and argv[1] == "--self-test":
        return self_test(argv[2])
    if len(argv) != 2:
        print(__doc__.split("\n\n")[1], file=sys.stderr)
        return 2
    files = sorted(glob.glob(os.path.join(argv[1], "*.yaml")))
    if not files:
        print(f"test_manifests: no *.yaml in {argv[1]}", file=sys.stderr)
        return 2
    checker = Checker()
    loaded = checker.check(files)
    for e in checker.errors:
        print(f"FAULT {e}", file=sys.stderr)
    print(f"test_manifests: {len(loaded)} documents in {len(files)} files, {len(checker.errors)} faults", file=sys.stderr)
    return 1 if checker.errors else 0


if __name__ == "__main__":
    from manifest_mistakes import self_test  # noqa: E402  (next to this file)
    sys.exit(main(sys.argv))
