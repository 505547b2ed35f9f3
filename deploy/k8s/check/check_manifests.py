#!/usr/bin/env python3
"""check_manifests.py - offline checks of Kubernetes manifests that a schema alone misses.

1. Unknown fields: every key of every object must be a field of the Kubernetes API model at
   that place (Debian's python3-kubernetes models; a misspelt `readinessprobe` would otherwise
   be dropped silently by the API server and the probe lost).
2. With --kustomize DIR: the manifests of deploy/k8s hang together: kustomization.yaml lists
   every manifest in DIR; the Service, PodDisruptionBudget and Deployment selectors match the
   pod labels; the HorizontalPodAutoscaler targets the Deployment; every ConfigMap, Secret and
   PersistentVolumeClaim the pods use exists; probes name container ports; the grace period
   outlasts the preStop sleep plus SDFD_DRAIN_SECONDS; containers run as non-root with a
   read-only root and no capabilities, with requests and limits; the Prometheus annotation
   names the HTTP port; SDFD_THREADS fits the CPU limit; SDFD_DATA_DIR is mounted read-write
   from a ReadWriteMany claim (sdfd could not create it on the read-only root); the memory
   limit covers 16 MiB + 2.9 x SDFD_MAX_RESIDENT_BYTES + SDFD_MAX_BUFFERED_BYTES +
   SDFD_MAX_VOLUME_BYTES (docs/deploy.md, "Sizing replicas").

    python3 deploy/k8s/check/check_manifests.py FILE.yaml...
    python3 deploy/k8s/check/check_manifests.py --kustomize deploy/k8s

Exits 1 and names each problem if there is one.
"""
import glob
import os
import re
import sys

import kubernetes.client.models as models
import yaml

# apiVersion/kind -> model class. python3-kubernetes 22.6 predates autoscaling/v2, whose fields
# are those of autoscaling/v2beta2.
ALIASES = {("autoscaling/v2", "HorizontalPodAutoscaler"): "V2beta2HorizontalPodAutoscaler"}
PRIMITIVES = {"str", "int", "float", "bool", "object", "datetime", "date"}


def model_name(api_version, kind):
    if (api_version, kind) in ALIASES:
        return ALIASES[(api_version, kind)]
    version = api_version.split("/")[-1]
    return version[0].upper() + version[1:] + kind


def unknown_fields(value, type_name, path):
    """Paths of keys that are no field of `type_name` (an openapi type string), recursively."""
    if value is None or type_name in PRIMITIVES:
        return []
    m = re.fullmatch(r"list\[(.+)\]", type_name)
    if m:
        return [p for i, v in enumerate(value or [])
                for p in unknown_fields(v, m.group(1), f"{path}[{i}]")]
    m = re.fullmatch(r"dict\(str, (.+)\)", type_name)
    if m:
        return [p for k, v in (value or {}).items()
                for p in unknown_fields(v, m.group(1), f"{path}.{k}")]
    cls = getattr(models, type_name, None)
    if cls is None or not isinstance(value, dict):
        return [f"{path}: expected an object of type {type_name}"] if cls else []
    by_json = {j: a for a, j in cls.attribute_map.items()}
    out = []
    for key, v in value.items():
        if key not in by_json:
            out.append(f"{path}.{key}: unknown field of {type_name}")
        else:
            out += unknown_fields(v, cls.openapi_types[by_json[key]], f"{path}.{key}")
    return out


def load(files):
    """[(file, object)] of every document, skipping kustomization.yaml."""
    out = []
    for f in files:
        with open(f) as fh:
            for doc in yaml.safe_load_all(fh):
                if doc and doc.get("kind") != "Kustomization":
                    out.append((f, doc))
    return out


def check_fields(docs):
    problems = []
    for f, d in docs:
        name = model_name(d.get("apiVersion", ""), d.get("kind", ""))
        if not hasattr(models, name):
            problems.append(f"{f}: no model for {d.get('apiVersion')} {d.get('kind')}")
            continue
        problems += [f"{f}: {p}" for p in unknown_fields(d, name, d["kind"])]
    return problems


def by_kind(docs, kind):
    return [d for _, d in docs if d["kind"] == kind]


def matches(selector, labels):
    return bool(selector) and all(labels.get(k) == v for k, v in selector.items())


def check_pod(dep, names):
    """The Deployment's pod template against the rest; returns problems."""
    problems = []
    spec = dep["spec"]["template"]["spec"]
    annotations = dep["spec"]["template"]["metadata"].get("annotations", {})
    if not spec.get("securityContext", {}).get("runAsNonRoot"):
        problems.append("the pod does not require runAsNonRoot")
    for vol in spec.get("volumes", []):
        claim = vol.get("persistentVolumeClaim", {}).get("claimName")
        if claim and claim not in names["PersistentVolumeClaim"]:
            problems.append(f"volume {vol['name']}: no PersistentVolumeClaim {claim}")
    for c in spec["containers"]:
        problems += check_container(c, spec, annotations, names)
    return problems


def check_container(c, pod, annotations, names):
    problems = []
    sc = c.get("securityContext", {})
    if not (sc.get("readOnlyRootFilesystem") and "ALL" in sc.get("capabilities", {}).get("drop", [])
            and sc.get("allowPrivilegeEscalation") is False):
        problems.append(f"{c['name']}: needs a read-only root, drop ALL, no privilege escalation")
    res = c.get("resources", {})
    for part in ("requests", "limits"):
        if not {"cpu", "memory"} <= set(res.get(part, {})):
            problems.append(f"{c['name']}: resources.{part} needs cpu and memory")
    ports = {p["name"]: p["containerPort"] for p in c.get("ports", [])}
    for probe in ("readinessProbe", "livenessProbe"):
        port = c.get(probe, {}).get("httpGet", {}).get("port")
        if port not in ports:
            problems.append(f"{c['name']}: {probe} port {port} is no container port")
    if str(ports.get("http")) != annotations.get("prometheus.io/port"):
        problems.append("the prometheus.io/port annotation is not the http port")
    env = {}
    for ref in c.get("envFrom", []):
        cm = ref.get("configMapRef", {}).get("name")
        if cm not in names["ConfigMap"]:
            problems.append(f"{c['name']}: no ConfigMap {cm}")
        else:
            env.update(names["ConfigMap"][cm])
    for e in c.get("env", []):
        key = e.get("valueFrom", {}).get("secretKeyRef")
        if key and key.get("key") not in names["Secret"].get(key.get("name"), {}):
            problems.append(f"{c['name']}: no Secret {key.get('name')} with key {key.get('key')}")
    cmd = c.get("lifecycle", {}).get("preStop", {}).get("exec", {}).get("command", [])
    sleep = int(cmd[1]) if len(cmd) == 2 and cmd[0] == "sleep" else 0
    drain = int(env.get("SDFD_DRAIN_SECONDS", 30))
    if sleep == 0:
        problems.append(f"{c['name']}: no preStop sleep")
    if pod.get("terminationGracePeriodSeconds", 30) <= sleep + drain:
        problems.append(f"terminationGracePeriodSeconds is not above preStop {sleep} s + drain "
                        f"{drain} s")
    cpu = str(res.get("limits", {}).get("cpu", "0"))
    cpus = int(cpu[:-1]) / 1000 if cpu.endswith("m") else float(cpu)
    if int(env.get("SDFD_THREADS", 0)) == 0 or int(env["SDFD_THREADS"]) > max(cpus, 1):
        problems.append("SDFD_THREADS must be set, at most the CPU limit")
    problems += check_store(c, pod, env, names["claims"])
    problems += check_memory(c, env)
    return problems


def check_store(c, pod, env, claims):
    """SDFD_DATA_DIR: a read-write mount of a ReadWriteMany claim, mounted read-write."""
    path = env.get("SDFD_DATA_DIR")
    if not path:
        return [f"{c['name']}: SDFD_DATA_DIR is not set (replicas would not share a store)"]
    mounts = [m for m in c.get("volumeMounts", []) if m.get("mountPath") == path]
    if len(mounts) != 1 or mounts[0].get("readOnly"):
        return [f"{c['name']}: SDFD_DATA_DIR {path} is not one read-write volumeMount"]
    vols = {v["name"]: v for v in pod.get("volumes", [])}
    pvc = vols.get(mounts[0]["name"], {}).get("persistentVolumeClaim")
    if not pvc or pvc.get("readOnly"):
        return [f"{c['name']}: {path} is not a read-write persistentVolumeClaim"]
    claim = claims.get(pvc.get("claimName"))
    if claim and "ReadWriteMany" not in claim.get("spec", {}).get("accessModes", []):
        return [f"PersistentVolumeClaim {pvc['claimName']}: not ReadWriteMany, so replicas on "
                f"different nodes cannot share it"]
    return []


def quantity(text):
    """A Kubernetes memory quantity (512Mi, 1Gi, 1G, 1000) in bytes."""
    units = {"Ki": 2**10, "Mi": 2**20, "Gi": 2**30, "Ti": 2**40, "k": 10**3, "M": 10**6,
             "G": 10**9, "T": 10**12}
    m = re.fullmatch(r"(\d+)([KMGT]i?|k)?", str(text))
    if not m:
        raise ValueError(f"memory quantity {text!r}")
    return int(m.group(1)) * units.get(m.group(2), 1)


def check_memory(c, env):
    limit = c.get("resources", {}).get("limits", {}).get("memory")
    if limit is None:
        return []
    need = (16 * 2**20 + 2.9 * int(env.get("SDFD_MAX_RESIDENT_BYTES", 0))
            + int(env.get("SDFD_MAX_BUFFERED_BYTES", 2**31))
            + int(env.get("SDFD_MAX_VOLUME_BYTES", 2**32)))
    if quantity(limit) < need:
        return [f"{c['name']}: memory limit {limit} under the {need / 2**20:.0f} MiB the "
                f"ConfigMap's budgets allow"]
    return []


def check_kustomize(directory):
    kust = yaml.safe_load(open(os.path.join(directory, "kustomization.yaml")))
    listed = set(kust.get("resources", []))
    present = {os.path.basename(f) for f in glob.glob(os.path.join(directory, "*.yaml"))}
    present.discard("kustomization.yaml")
    problems = [f"kustomization.yaml: {f} is not listed" for f in sorted(present - listed)]
    problems += [f"kustomization.yaml: {f} does not exist" for f in sorted(listed - present)]
    docs = load(sorted(os.path.join(directory, f) for f in present & listed))
    names = {k: {} for k in ("ConfigMap", "Secret", "PersistentVolumeClaim")}
    for k in list(names):
        for d in by_kind(docs, k):
            names[k][d["metadata"]["name"]] = {**d.get("data", {}), **d.get("stringData", {})}
    names["claims"] = {d["metadata"]["name"]: d for d in by_kind(docs, "PersistentVolumeClaim")}
    deps = by_kind(docs, "Deployment")
    if len(deps) != 1:
        return problems + [f"expected one Deployment, found {len(deps)}"]
    dep = deps[0]
    labels = dep["spec"]["template"]["metadata"]["labels"]
    if not matches(dep["spec"]["selector"]["matchLabels"], labels):
        problems.append("the Deployment's selector does not match its pod labels")
    for kind, get in (("Service", lambda d: d["spec"]["selector"]),
                      ("PodDisruptionBudget", lambda d: d["spec"]["selector"]["matchLabels"])):
        for d in by_kind(docs, kind):
            if not matches(get(d), labels):
                problems.append(f"{kind} {d['metadata']['name']}: selector matches no pod")
    for d in by_kind(docs, "HorizontalPodAutoscaler"):
        t = d["spec"]["scaleTargetRef"]
        if (t["kind"], t["name"]) != ("Deployment", dep["metadata"]["name"]):
            problems.append(f"HorizontalPodAutoscaler targets {t['kind']} {t['name']}")
    return problems + check_pod(dep, names)


def main(argv):
    if len(argv) == 2 and argv[0] == "--kustomize":
        d = argv[1]
        files = sorted(glob.glob(os.path.join(d, "*.yaml")))
        problems = check_fields(load(files)) + check_kustomize(d)
    elif argv and not argv[0].startswith("-"):
        problems = check_fields(load(argv))
    else:
        print(__doc__)
        return 2
    for p in problems:
        print(p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
