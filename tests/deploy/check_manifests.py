#!/usr/bin/env python3
"""Checks the Kubernetes manifests of deploy/k8s/ against the schema of their
objects, as far as the fields they use: apiVersion and kind, required fields,
field names (a misspelt field is silently dropped by a lenient client, so
every key must be one the object's type has), value types and formats
(names, ports, quantities, probes), and references inside a manifest
(selectors match template labels, volume mounts name declared volumes,
$(VAR) references name declared env vars, a StatefulSet's serviceName names
a headless Service). Then voxvis's own rules: the fleet's --fleet lists the
StatefulSet's pod names exactly.

No Kubernetes cluster or OpenAPI document is available offline (Debian's
kubectl validates against a server's schema), so the schema here is written
from the Kubernetes API reference (v1.28: core/v1 Pod, Service,
PersistentVolumeClaim; apps/v1 Deployment, StatefulSet; batch/v1 Job;
policy/v1 PodDisruptionBudget), limited to the fields voxvis's manifests may
use: a field outside it is reported, to be checked and added.

Usage: check_manifests.py DIR   (exit 1 with one line per problem)
       check_manifests.py --expect FILE DIR
         (the checker's own test: exit 0 only when every line of FILE is
         part of some problem reported, i.e. each known mistake is caught)
"""
import glob
import os
import re
import sys

import yaml

DNS_LABEL = re.compile(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$")
DNS_SUBDOMAIN = re.compile(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?(\.[a-z0-9]([-a-z0-9]*[a-z0-9])?)*$")
PORT_NAME = re.compile(r"^(?=.*[a-z])[a-z0-9]([-a-z0-9]*[a-z0-9])?$")  # IANA_SVC_NAME
ENV_NAME = re.compile(r"^[-._a-zA-Z][-._a-zA-Z0-9]*$")
QUANTITY = re.compile(r"^[0-9]+(\.[0-9]+)?(m|k|M|G|T|P|E|Ki|Mi|Gi|Ti|Pi|Ei)?$")
LABEL_VALUE = re.compile(r"^(([A-Za-z0-9][-A-Za-z0-9_.]*)?[A-Za-z0-9])?$")

KINDS = {
    ("v1", "Pod"), ("v1", "Service"), ("v1", "PersistentVolumeClaim"), ("v1", "ConfigMap"),
    ("apps/v1", "Deployment"), ("apps/v1", "StatefulSet"), ("batch/v1", "Job"),
    ("policy/v1", "PodDisruptionBudget"),
}

# The keys each structure may have (the subset of the API voxvis uses).
KEYS = {
    "object": {"apiVersion", "kind", "metadata", "spec", "data"},
    "metadata": {"name", "namespace", "labels", "annotations"},
    "podSpec": {"containers", "initContainers", "volumes", "restartPolicy", "securityContext",
                "terminationGracePeriodSeconds", "serviceAccountName", "nodeSelector", "affinity",
                "tolerations", "shareProcessNamespace", "hostNetwork"},
    "podSecurityContext": {"runAsNonRoot", "runAsUser", "runAsGroup", "fsGroup", "seccompProfile"},
    "container": {"name", "image", "command", "args", "env", "ports", "resources", "volumeMounts",
                  "securityContext", "startupProbe", "readinessProbe", "livenessProbe", "workingDir",
                  "imagePullPolicy"},
    "containerSecurityContext": {"allowPrivilegeEscalation", "readOnlyRootFilesystem", "capabilities",
                                 "runAsNonRoot", "runAsUser", "runAsGroup"},
    "capabilities": {"add", "drop"},
    "env": {"name", "value", "valueFrom"},
    "valueFrom": {"fieldRef", "secretKeyRef", "configMapKeyRef"},
    "fieldRef": {"fieldPath", "apiVersion"},
    "containerPort": {"name", "containerPort", "hostPort", "protocol"},
    "resources": {"requests", "limits"},
    "volumeMount": {"name", "mountPath", "readOnly", "subPath"},
    "probe": {"exec", "httpGet", "tcpSocket", "grpc", "initialDelaySeconds", "periodSeconds",
              "timeoutSeconds", "successThreshold", "failureThreshold"},
    "exec": {"command"},
    "grpc": {"port", "service"},
    "volume": {"name", "emptyDir", "persistentVolumeClaim", "configMap", "secret"},
    "pvcSource": {"claimName", "readOnly"},
    "deploymentSpec": {"replicas", "selector", "template", "strategy", "minReadySeconds"},
    "statefulSetSpec": {"replicas", "selector", "template", "serviceName", "podManagementPolicy",
                        "updateStrategy", "volumeClaimTemplates", "minReadySeconds"},
    "jobSpec": {"completions", "parallelism", "completionMode", "backoffLimit", "template",
                "activeDeadlineSeconds", "ttlSecondsAfterFinished"},
    "template": {"metadata", "spec"},
    "selector": {"matchLabels"},
    "serviceSpec": {"selector", "ports", "clusterIP", "type"},
    "servicePort": {"name", "port", "targetPort", "protocol"},
    "pvcSpec": {"accessModes", "resources", "storageClassName"},
    "pvcTemplate": {"metadata", "spec"},
    "pdbSpec": {"selector", "minAvailable", "maxUnavailable"},
    "strategy": {"type", "rollingUpdate"},
}


class Checker:
    def __init__(self):
        self.problems = []

    def fail(self, where, message):
        self.problems.append(f"{where}: {message}")

    def keys(self, where, value, kind, required=()):
        if not isinstance(value, dict):
            self.fail(where, f"must be a mapping, got {type(value).__name__}")
            return False
        for key in value:
            if key not in KEYS[kind]:
                self.fail(f"{where}.{key}", f"not a field of {kind}")
        for key in required:
            if key not in value:
                self.fail(where, f"missing required field '{key}'")
        return True

    def integer(self, where, value, low, high):
        if not isinstance(value, int) or isinstance(value, bool) or not low <= value <= high:
            self.fail(where, f"must be an integer in [{low}, {high}], got {value!r}")

    def name(self, where, value, pattern=DNS_SUBDOMAIN, limit=253):
        if not isinstance(value, str) or len(value) > limit or not pattern.match(value):
            self.fail(where, f"not a valid name: {value!r}")

    def quantities(self, where, value):
        if not self.keys(where, value, "resources"):
            return
        for part in ("requests", "limits"):
            for res, q in (value.get(part) or {}).items():
                if res not in ("cpu", "memory", "ephemeral-storage", "storage"):
                    self.fail(f"{where}.{part}.{res}", "unknown resource")
                if not QUANTITY.match(str(q)):
                    self.fail(f"{where}.{part}.{res}", f"not a quantity: {q!r}")

    def labels(self, where, labels):
        for k, v in (labels or {}).items():
            if not isinstance(v, str) or not LABEL_VALUE.match(v) or len(v) > 63:
                self.fail(f"{where}.{k}", f"not a label value: {v!r}")

    def metadata(self, where, meta, named=True):
        if not self.keys(where, meta, "metadata", ("name",) if named else ()):
            return
        if "name" in meta:
            self.name(f"{where}.name", meta["name"])
        self.labels(f"{where}.labels", meta.get("labels"))
        for k, v in (meta.get("annotations") or {}).items():
            if not isinstance(v, str):
                self.fail(f"{where}.annotations.{k}", f"must be a string, got {v!r}")

    def probe(self, where, probe, ports):
        if not self.keys(where, probe, "probe"):
            return
        handlers = [h for h in ("exec", "httpGet", "tcpSocket", "grpc") if h in probe]
        if len(handlers) != 1:
            self.fail(where, f"needs exactly one handler, has {handlers}")
        if "grpc" in probe and self.keys(f"{where}.grpc", probe["grpc"], "grpc", ("port",)):
            # The grpc probe's port is a number (no named ports), one the container declares.
            self.integer(f"{where}.grpc.port", probe["grpc"]["port"], 1, 65535)
            if ports and probe["grpc"]["port"] not in ports:
                self.fail(f"{where}.grpc.port", f"{probe['grpc']['port']} is not a port of the container")
        if "exec" in probe and self.keys(f"{where}.exec", probe["exec"], "exec", ("command",)):
            if not all(isinstance(a, str) for a in probe["exec"]["command"]):
                self.fail(f"{where}.exec.command", "must be strings")
        for f in ("periodSeconds", "failureThreshold", "timeoutSeconds", "initialDelaySeconds"):
            if f in probe:
                self.integer(f"{where}.{f}", probe[f], 0 if f == "initialDelaySeconds" else 1, 1 << 31)

    def container(self, where, c, volumes):
        if not self.keys(where, c, "container", ("name", "image")):
            return
        self.name(f"{where}.name", c["name"], DNS_LABEL, 63)
        env = set()
        for i, e in enumerate(c.get("env") or []):
            w = f"{where}.env[{i}]"
            if self.keys(w, e, "env", ("name",)):
                if not ENV_NAME.match(str(e["name"])):
                    self.fail(f"{w}.name", f"not an environment variable name: {e['name']!r}")
                if "value" in e and not isinstance(e["value"], str):
                    self.fail(f"{w}.value", f"must be a string, got {e['value']!r}")
                if "valueFrom" in e and self.keys(f"{w}.valueFrom", e["valueFrom"], "valueFrom"):
                    ref = e["valueFrom"].get("fieldRef")
                    if ref is not None and self.keys(f"{w}.valueFrom.fieldRef", ref, "fieldRef", ("fieldPath",)):
                        if not re.match(r"^(metadata\.(name|namespace|uid)|spec\.nodeName|status\.podIP)$",
                                        ref["fieldPath"]):
                            self.fail(f"{w}.valueFrom.fieldRef.fieldPath", f"unsupported: {ref['fieldPath']}")
                env.add(e["name"])
        for field in ("command", "args"):
            for j, a in enumerate(c.get(field) or []):
                if not isinstance(a, str):
                    self.fail(f"{where}.{field}[{j}]", f"must be a string, got {a!r}")
                    continue
                # Kubernetes expands $(NAME) where NAME is an env var of the
                # container and leaves any other $(...) (a shell's) alone.
                for ref in re.findall(r"\$\(([A-Z_][A-Z0-9_]*)\)", a):
                    if ref not in env:
                        self.fail(f"{where}.{field}[{j}]", f"$({ref}) names no env var of the container")
        ports = set()
        names = set()
        for j, p in enumerate(c.get("ports") or []):
            w = f"{where}.ports[{j}]"
            if self.keys(w, p, "containerPort", ("containerPort",)):
                self.integer(f"{w}.containerPort", p["containerPort"], 1, 65535)
                ports.add(p["containerPort"])
                if "hostPort" in p:
                    self.integer(f"{w}.hostPort", p["hostPort"], 1, 65535)
                if "name" in p:
                    self.name(f"{w}.name", p["name"], PORT_NAME, 15)
                    names.add(p["name"])
        if "resources" in c:
            self.quantities(f"{where}.resources", c["resources"])
        for j, m in enumerate(c.get("volumeMounts") or []):
            w = f"{where}.volumeMounts[{j}]"
            if self.keys(w, m, "volumeMount", ("name", "mountPath")):
                if m["name"] not in volumes:
                    self.fail(f"{w}.name", f"'{m['name']}' is not a volume of the pod")
                if not str(m["mountPath"]).startswith("/"):
                    self.fail(f"{w}.mountPath", "must be absolute")
        for probe in ("startupProbe", "readinessProbe", "livenessProbe"):
            if probe in c:
                self.probe(f"{where}.{probe}", c[probe], ports)
        if "securityContext" in c and self.keys(f"{where}.securityContext", c["securityContext"],
                                                 "containerSecurityContext"):
            caps = c["securityContext"].get("capabilities")
            if caps is not None:
                self.keys(f"{where}.securityContext.capabilities", caps, "capabilities")
        return names

    def pod_spec(self, where, spec, extra_volumes=(), job=False):
        if not self.keys(where, spec, "podSpec", ("containers",)):
            return
        volumes = set(extra_volumes)
        for i, v in enumerate(spec.get("volumes") or []):
            w = f"{where}.volumes[{i}]"
            if self.keys(w, v, "volume", ("name",)):
                self.name(f"{w}.name", v["name"], DNS_LABEL, 63)
                sources = [s for s in ("emptyDir", "persistentVolumeClaim", "configMap", "secret") if s in v]
                if len(sources) != 1:
                    self.fail(w, f"needs exactly one source, has {sources}")
                if "persistentVolumeClaim" in v:
                    self.keys(f"{w}.persistentVolumeClaim", v["persistentVolumeClaim"], "pvcSource", ("claimName",))
                volumes.add(v["name"])
        if not spec.get("containers"):
            self.fail(f"{where}.containers", "must not be empty")
        seen = set()
        for i, c in enumerate(spec.get("containers") or []):
            self.container(f"{where}.containers[{i}]", c, volumes)
            if isinstance(c, dict) and c.get("name") in seen:
                self.fail(f"{where}.containers[{i}].name", f"'{c['name']}' is given twice")
            if isinstance(c, dict):
                seen.add(c.get("name"))
        policy = spec.get("restartPolicy", "Always")
        allowed = ("Never", "OnFailure") if job else ("Always", "OnFailure", "Never")
        if policy not in allowed:
            self.fail(f"{where}.restartPolicy", f"must be one of {allowed}, got {policy!r}")
        if "securityContext" in spec:
            self.keys(f"{where}.securityContext", spec["securityContext"], "podSecurityContext")
        if "terminationGracePeriodSeconds" in spec:
            self.integer(f"{where}.terminationGracePeriodSeconds", spec["terminationGracePeriodSeconds"], 0, 1 << 31)

    def template(self, where, spec, extra_volumes=(), job=False):
        t = spec.get("template")
        if not self.keys(f"{where}.template", t, "template", ("spec",)):
            return {}
        meta = t.get("metadata") or {}
        self.metadata(f"{where}.template.metadata", meta, named=False)
        self.pod_spec(f"{where}.template.spec", t["spec"], extra_volumes, job)
        return meta.get("labels") or {}

    def selector(self, where, spec, labels):
        sel = spec.get("selector")
        if not self.keys(f"{where}.selector", sel, "selector", ("matchLabels",)):
            return
        for k, v in sel["matchLabels"].items():
            if labels.get(k) != v:
                self.fail(f"{where}.selector.matchLabels.{k}", "does not match the pod template's labels")

    def pvc_spec(self, where, spec):
        if not self.keys(where, spec, "pvcSpec", ("accessModes", "resources")):
            return
        for m in spec["accessModes"]:
            if m not in ("ReadWriteOnce", "ReadOnlyMany", "ReadWriteMany", "ReadWriteOncePod"):
                self.fail(f"{where}.accessModes", f"unknown mode {m!r}")
        self.quantities(f"{where}.resources", spec["resources"])
        if "storage" not in (spec["resources"].get("requests") or {}):
            self.fail(f"{where}.resources.requests", "missing storage")

    def document(self, where, doc, services):
        if not self.keys(where, doc, "object", ("apiVersion", "kind", "metadata")):
            return
        kind = doc["kind"]
        if (doc["apiVersion"], kind) not in KINDS:
            self.fail(where, f"unknown apiVersion/kind {doc['apiVersion']}/{kind}")
            return
        where = f"{where} ({kind} {doc['metadata'].get('name')})"
        self.metadata(f"{where}.metadata", doc["metadata"])
        if kind == "ConfigMap":
            return
        spec = doc.get("spec")
        if spec is None:
            self.fail(where, "missing required field 'spec'")
            return
        w = f"{where}.spec"
        if kind == "Pod":
            self.pod_spec(w, spec)
        elif kind == "Deployment":
            if self.keys(w, spec, "deploymentSpec", ("selector", "template")):
                self.selector(w, spec, self.template(w, spec))
                if "strategy" in spec:
                    self.keys(f"{w}.strategy", spec["strategy"], "strategy")
                    if spec["strategy"].get("type") not in ("Recreate", "RollingUpdate"):
                        self.fail(f"{w}.strategy.type", f"unknown {spec['strategy'].get('type')!r}")
        elif kind == "StatefulSet":
            if self.keys(w, spec, "statefulSetSpec", ("selector", "template", "serviceName")):
                claims = []
                for i, t in enumerate(spec.get("volumeClaimTemplates") or []):
                    if self.keys(f"{w}.volumeClaimTemplates[{i}]", t, "pvcTemplate", ("metadata", "spec")):
                        self.metadata(f"{w}.volumeClaimTemplates[{i}].metadata", t["metadata"])
                        self.pvc_spec(f"{w}.volumeClaimTemplates[{i}].spec", t["spec"])
                        claims.append(t["metadata"].get("name"))
                self.selector(w, spec, self.template(w, spec, claims))
                if spec.get("podManagementPolicy", "OrderedReady") not in ("OrderedReady", "Parallel"):
                    self.fail(f"{w}.podManagementPolicy", "must be OrderedReady or Parallel")
                if spec["serviceName"] not in services:
                    self.fail(f"{w}.serviceName", f"'{spec['serviceName']}' names no Service of the manifests")
                elif services[spec["serviceName"]].get("clusterIP") != "None":
                    self.fail(f"{w}.serviceName", "its Service must be headless (clusterIP: None)")
        elif kind == "Job":
            if self.keys(w, spec, "jobSpec", ("template",)):
                self.template(w, spec, job=True)
                mode = spec.get("completionMode", "NonIndexed")
                if mode not in ("NonIndexed", "Indexed"):
                    self.fail(f"{w}.completionMode", f"unknown {mode!r}")
                if mode == "Indexed" and "completions" not in spec:
                    self.fail(w, "an Indexed Job needs completions")
                for f in ("completions", "parallelism", "backoffLimit"):
                    if f in spec:
                        self.integer(f"{w}.{f}", spec[f], 0, 100000)
        elif kind == "Service":
            if self.keys(w, spec, "serviceSpec", ("ports",)):
                for i, p in enumerate(spec["ports"]):
                    if self.keys(f"{w}.ports[{i}]", p, "servicePort", ("port",)):
                        self.integer(f"{w}.ports[{i}].port", p["port"], 1, 65535)
        elif kind == "PersistentVolumeClaim":
            self.pvc_spec(w, spec)
        elif kind == "PodDisruptionBudget":
            if self.keys(w, spec, "pdbSpec", ("selector",)):
                if ("minAvailable" in spec) == ("maxUnavailable" in spec):
                    self.fail(w, "needs exactly one of minAvailable and maxUnavailable")
                self.keys(f"{w}.selector", spec["selector"], "selector", ("matchLabels",))


def fleet_rules(checker, path, docs):
    """voxvis's own: a StatefulSet's --fleet names its pods exactly, and each
    pod passes --shard=$(POD_NAME) from metadata.name."""
    for doc in docs:
        if not isinstance(doc, dict) or doc.get("kind") != "StatefulSet":
            continue
        name = doc["metadata"]["name"]
        replicas = doc["spec"].get("replicas", 1)
        pods = [f"{name}-{i}" for i in range(replicas)]
        for c in doc["spec"]["template"]["spec"]["containers"]:
            args = c.get("args") or []
            fleet = [a.split("=", 1)[1] for a in args if a.startswith("--fleet=")]
            if fleet != [",".join(pods)]:
                checker.fail(path, f"StatefulSet {name}: --fleet must be {','.join(pods)} for {replicas} replicas, "
                                   f"got {fleet}")
            if "--shard=$(POD_NAME)" not in args:
                checker.fail(path, f"StatefulSet {name}: each pod must pass --shard=$(POD_NAME)")


def main():
    args = sys.argv[1:]
    expect = None
    if len(args) >= 2 and args[0] == "--expect":
        with open(args[1], encoding="utf-8") as f:
            expect = [line.strip() for line in f if line.strip() and not line.startswith("#")]
        args = args[2:]
    directory = args[0] if args else os.path.join(os.path.dirname(__file__), "../../deploy/k8s")
    checker = Checker()
    files = sorted(glob.glob(os.path.join(directory, "*.yaml")))
    if not files:
        print(f"{directory}: no manifests", file=sys.stderr)
        return 1
    count = 0
    for path in files:
        with open(path, encoding="utf-8") as f:
            try:
                docs = [d for d in yaml.safe_load_all(f) if d is not None]
            except yaml.YAMLError as e:
                checker.fail(path, f"not YAML: {e}")
                continue
        services = {d["metadata"]["name"]: d.get("spec") or {}
                    for d in docs if isinstance(d, dict) and d.get("kind") == "Service"}
        for i, doc in enumerate(docs):
            checker.document(f"{os.path.basename(path)}[{i}]", doc, services)
            count += 1
        fleet_rules(checker, os.path.basename(path), docs)
    for p in checker.problems:
        print(p, file=sys.stderr)
    print(f"{count} objects in {len(files)} manifests: {len(checker.problems)} problems")
    if expect is not None:
        missed = [e for e in expect if not any(e in p for p in checker.problems)]
        for e in missed:
            print(f"not caught: {e}", file=sys.stderr)
        return 1 if missed else 0
    return 1 if checker.problems else 0


if __name__ == "__main__":
    sys.exit(main())
