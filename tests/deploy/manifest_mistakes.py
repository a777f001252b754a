"""test_manifests.py --self-test DIR: each mistake below, made in a copy of
DIR's manifests, must be reported with the words given; the manifests as
they are must pass. So the check is known to fail when a manifest breaks."""
import copy
import glob
import os
import sys

import yaml


def find(loaded, kind):
    """The first document of `kind`; for Job, the Indexed one (verify-job.yaml)."""
    if kind == "Job":
        return next(doc for _, doc in loaded
                    if doc.get("kind") == "Job" and doc["spec"].get("completionMode") == "Indexed")
    return next(doc for _, doc in loaded if doc.get("kind") == kind)


def pod(doc):
    return doc["spec"] if doc["kind"] == "Pod" else doc["spec"]["template"]["spec"]


def container(loaded, kind):
    return pod(find(loaded, kind))["containers"][-1]


# (what is broken, how, words the report must hold)
MISTAKES = [
    ("a kind its apiVersion does not serve",
     lambda d: find(d, "StatefulSet").update(apiVersion="batch/v1"), "not served by batch/v1"),
    ("an apiVersion that does not exist",
     lambda d: find(d, "Deployment").update(apiVersion="apps/v1beta3"), "served by no API group"),
    ("a misspelt field",
     lambda d: container(d, "StatefulSet")["ports"][0].update(containerport=1), "no such field in V1ContainerPort"),
    ("a required field missing (Pod containers)",
     lambda d: pod(find(d, "Pod")).pop("containers"), "`containers`, must not be `None`"),
    ("a required field missing (gRPC probe port)",
     lambda d: container(d, "StatefulSet")["readinessProbe"]["grpc"].pop("port"), "required field 'port'"),
    ("a wrong type",
     lambda d: find(d, "StatefulSet")["spec"].update(replicas="3"), "must be an integer"),
    ("a selector the template's labels do not match",
     lambda d: find(d, "Deployment")["spec"]["selector"]["matchLabels"].update({"app.kubernetes.io/name": "x"}),
     "does not match the template's labels"),
    ("a probe on an undeclared port",
     lambda d: container(d, "StatefulSet")["livenessProbe"]["grpc"].update(port=50052), "none of the container's ports"),
    ("a mount of an undeclared volume",
     lambda d: container(d, "Job")["volumeMounts"][0].update(name="result"), "'result' is no volume of the pod"),
    ("a quantity that is not one",
     lambda d: container(d, "StatefulSet")["resources"]["requests"].update(memory="512MB"), "not a Kubernetes quantity"),
    ("a request above its limit",
     lambda d: container(d, "Deployment")["resources"]["requests"].update(memory="4Gi"), "memory request above its limit"),
    ("an Indexed Job without completions",
     lambda d: find(d, "Job")["spec"].pop("completions"), "an Indexed Job needs completions"),
    ("a Job's pods restarting Always",
     lambda d: pod(find(d, "Job")).update(restartPolicy="Always"), "Never or OnFailure"),
    ("a StatefulSet whose Service is not there",
     lambda d: find(d, "StatefulSet")["spec"].update(serviceName="voxvis-headless"), "is no Service here"),
    ("a fleet list out of step with the replicas",
     lambda d: find(d, "StatefulSet")["spec"].update(replicas=4), "is not the StatefulSet's pods"),
    ("a $(VAR) of no env variable",
     lambda d: container(d, "StatefulSet")["env"][0].update(name="POD"), "$(POD_NAME) names no env variable"),
    ("a PodDisruptionBudget selecting nothing",
     lambda d: find(d, "PodDisruptionBudget")["spec"]["selector"]["matchLabels"].update(app="x"), "selects no workload"),
    ("a claim no manifest defines",
     lambda d: pod(find(d, "Deployment"))["volumes"][0]["persistentVolumeClaim"].update(claimName="voxvis-dat"),
     "claim 'voxvis-dat' is defined by no manifest"),
    ("a Prometheus port the pod does not open",
     lambda d: find(d, "StatefulSet")["spec"]["template"]["metadata"]["annotations"].update({"prometheus.io/port": "9091"}),
     "9091 is none of the containers' ports"),
]


def self_test(directory):
    from test_manifests import Checker
    loaded = []
    for path in sorted(glob.glob(os.path.join(directory, "*.yaml"))):
        for i, doc in enumerate(yaml.safe_load_all(open(path, encoding="utf-8"))):
            if doc is not None:
                loaded.append((f"{os.path.basename(path)}#{i}", doc))
    clean = Checker()
    clean.check_documents(copy.deepcopy(loaded))
    failed = [f"the manifests as they are: {e}" for e in clean.errors]
    caught = 0
    for what, breaks, words in MISTAKES:
        broken = copy.deepcopy(loaded)
        breaks(broken)
        checker = Checker()
        checker.check_documents(broken)
        if not any(words in e for e in checker.errors):
            failed.append(f"{what}: not reported as '{words}' (reported: {checker.errors or 'nothing'})")
        else:
            caught += 1
    for f in failed:
        print(f"FAIL {f}", file=sys.stderr)
    print(f"test_manifests --self-test: {caught} of {len(MISTAKES)} mistakes caught,"
          f" {len(clean.errors)} faults in the manifests as they are", file=sys.stderr)
    return 1 if failed else 0
