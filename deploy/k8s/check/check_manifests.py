#!/usr/bin/env python3
"""check_manifests.py - offline checks of Kubernetes manifests that a schema alone misses.

1. Unknown fields: every key of every object must be a field of the Kubernetes API model at
   that place (Debian's python3-kubernetes models; a misspelt `readinessprobe` would otherwise
   be dropped silently by the API server and the probe lost). With --kustomize, in every file
   the kustomization reads: its resources, its components' resources and every patch.
2. With --kustomize DIR (deploy/k8s, deploy/k8s/base, deploy/k8s/with-postgres): the objects
   DIR's kustomization makes hang together. They are built as kustomize builds them, as far as
   these checks need: resources (files, or directories with a kustomization of their own),
   then components (kind Component, whose resources are added and whose patches apply to
   everything so far), then patches (`patches` entries with a path or an inline patch and no
   target, and `patchesStrategicMerge`, matched by kind and name and merged key by key, lists
   replaced whole). Namespaces and images are not applied. Then:
   - every kustomization lists every manifest beside it, lists no file that is missing, and
     includes no directory that contains it (kustomize refuses the cycle);
   - every Service (with a selector), PodDisruptionBudget and NetworkPolicy selects the pods
     of exactly one workload (Deployment or StatefulSet); each workload's selector matches its
     pods; a StatefulSet's serviceName is a Service that selects its pods; the
     HorizontalPodAutoscaler targets the Deployment;
   - every ConfigMap (envFrom), Secret key (secretKeyRef) and PersistentVolumeClaim the pods
     use exists, and every volumeMount names a volume (or a volumeClaimTemplate);
   - every pod requires runAsNonRoot; every container has a read-only root, drops ALL
     capabilities, forbids privilege escalation, has cpu and memory requests and limits, and
     readiness and liveness probes (an httpGet probe names a container port);
   - the one Deployment (sdfd): its grace period outlasts the preStop sleep plus
     SDFD_DRAIN_SECONDS; the Prometheus annotation names the HTTP port; SDFD_THREADS fits the
     CPU limit; SDFD_CATALOG comes from a key of a Secret (not a ConfigMap or a literal: the URI
     holds a password); SDFD_DATA_DIR, if set, is the mount of an emptyDir (a cache of the
     replica's own: the replicas share the catalog, no file system);
     SDFD_REPLICA_ID is the pod's name (fieldRef metadata.name); no volume is a ReadWriteMany
     claim (the replicas share the catalog, no file system); the memory limit covers
     16 MiB + 2.9 x SDFD_MAX_RESIDENT_BYTES + SDFD_MAX_BUFFERED_BYTES + SDFD_MAX_VOLUME_BYTES
     (docs/deploy.md, "Sizing replicas");
   - a catalog URI whose host is a Service of the build (a name without dots, or
     NAME.NAMESPACE.svc...) names one of its ports; the NetworkPolicies of that Service's pods
     let the sdfd pods in on it; and when those pods run PostgreSQL's image (POSTGRES_PASSWORD
     from a Secret), the URI's user, password and database are its POSTGRES_USER,
     POSTGRES_PASSWORD and POSTGRES_DB.

    python3 deploy/k8s/check/check_manifests.py FILE.yaml...
    python3 deploy/k8s/check/check_manifests.py --kustomize deploy/k8s/with-postgres

Exits 1 and names each problem if there is one.
"""
import base64
import copy
import glob
import os
import re
import sys
import urllib.parse

import kubernetes.client.models as models
import yaml

# apiVersion/kind -> model class. python3-kubernetes 22.6 predates autoscaling/v2, whose fields
# are those of autoscaling/v2beta2.
ALIASES = {("autoscaling/v2", "HorizontalPodAutoscaler"): "V2beta2HorizontalPodAutoscaler"}
PRIMITIVES = {"str", "int", "float", "bool", "object", "datetime", "date"}
KUSTOMIZE_KINDS = {"Kustomization", "Component"}
WORKLOADS = ("Deployment", "StatefulSet")


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
    """[(file, object)] of every document, skipping kustomizations and components."""
    out = []
    for f in files:
        with open(f) as fh:
            for doc in yaml.safe_load_all(fh):
                if doc and doc.get("kind") not in KUSTOMIZE_KINDS:
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


# Building a kustomization ----------------------------------------------------------------------

def merge(target, patch):
    """A strategic merge patch as far as these manifests need: maps merged, the rest replaced."""
    for k, v in patch.items():
        if isinstance(v, dict) and isinstance(target.get(k), dict):
            merge(target[k], v)
        else:
            target[k] = copy.deepcopy(v)


def key(d):
    return d.get("kind"), d.get("metadata", {}).get("name")


class Build:
    """The objects a kustomization makes, the files it read and what was wrong with it."""

    def __init__(self):
        self.files = []
        self.problems = []

    def kustomization(self, directory, kinds):
        path = os.path.join(directory, "kustomization.yaml")
        if not os.path.isfile(path):
            self.problems.append(f"{directory}: no kustomization.yaml")
            return None
        kust = yaml.safe_load(open(path)) or {}
        if kust.get("kind", "Kustomization") not in kinds:
            self.problems.append(f"{path}: kind {kust.get('kind')}, expected {' or '.join(kinds)}")
        return kust

    def build(self, directory, docs, kinds=("Kustomization",)):
        """Adds what `directory` makes to docs (a list of [file, object]), returns it."""
        kust = self.kustomization(directory, kinds)
        if kust is None:
            return docs
        where = os.path.join(directory, "kustomization.yaml")
        listed = set()
        for r in kust.get("resources", []):
            path = os.path.normpath(os.path.join(directory, r))
            if os.path.isdir(path):
                if self.contains(path, directory, where):
                    continue
                docs = docs + self.build(path, [])
            elif os.path.isfile(path):
                listed.add(path)
                docs = docs + self.read(path)
            else:
                self.problems.append(f"{where}: resource {r} does not exist")
        for c in kust.get("components", []):
            path = os.path.normpath(os.path.join(directory, c))
            if not os.path.isdir(path):
                self.problems.append(f"{where}: component {c} is no directory")
            elif not self.contains(path, directory, where):
                docs = self.build(path, docs, ("Component",))
        for p in kust.get("patches", []) + kust.get("patchesStrategicMerge", []):
            if isinstance(p, dict) and p.get("target"):
                self.problems.append(f"{where}: a patch with a target is not checked here")
                continue
            if isinstance(p, dict) and "patch" in p:
                bodies = [(where, d) for d in yaml.safe_load_all(p["patch"]) if d]
                self.files += [(f, copy.deepcopy(d)) for f, d in bodies]
            else:
                path = os.path.normpath(os.path.join(directory, p["path"] if isinstance(p, dict)
                                                     else p))
                if not os.path.isfile(path):
                    self.problems.append(f"{where}: patch {path} does not exist")
                    continue
                listed.add(path)
                bodies = self.read(path)
            for f, body in bodies:
                targets = [d for _, d in docs if key(d) == key(body)]
                if not targets:
                    self.problems.append(f"{f}: the patch of {key(body)[0]} {key(body)[1]} "
                                         f"matches no object")
                for t in targets:
                    merge(t, body)
        present = {os.path.normpath(f) for f in glob.glob(os.path.join(directory, "*.yaml"))}
        present.discard(os.path.normpath(where))
        self.problems += [f"{where}: {os.path.basename(f)} is not listed"
                          for f in sorted(present - listed)]
        return docs

    def contains(self, path, directory, where):
        """True (a problem) when path, a directory included by `where`, contains directory."""
        if os.path.commonpath([os.path.abspath(path), os.path.abspath(directory)]) == \
                os.path.abspath(path):
            self.problems.append(f"{where}: includes {path}, which contains it (kustomize "
                                 f"refuses the cycle)")
            return True
        return False

    def read(self, path):
        docs = load([path])
        self.files += [(f, copy.deepcopy(d)) for f, d in docs]
        return [[f, d] for f, d in docs]


# Checks of the built objects -------------------------------------------------------------------

def by_kind(docs, kind):
    return [d for _, d in docs if d["kind"] == kind]


def matches(selector, labels):
    return bool(selector) and all(labels.get(k) == v for k, v in selector.items())


def secret_values(d):
    """A Secret's keys and values, stringData over data (as the API server does)."""
    out = {}
    for k, v in (d.get("data") or {}).items():
        try:
            out[k] = base64.b64decode(v).decode()
        except ValueError:
            out[k] = None
    out.update(d.get("stringData") or {})
    return out


def check_selectors(docs):
    problems = []
    workloads = [d for kind in WORKLOADS for d in by_kind(docs, kind)]
    pods = {f"{d['kind']} {d['metadata']['name']}": d["spec"]["template"]["metadata"]["labels"]
            for d in workloads}
    for d in workloads:
        if not matches(d["spec"]["selector"].get("matchLabels"),
                       d["spec"]["template"]["metadata"]["labels"]):
            problems.append(f"{d['kind']} {d['metadata']['name']}: its selector does not match "
                            f"its pod labels")
    selects = {"Service": lambda d: d["spec"].get("selector"),
               "PodDisruptionBudget": lambda d: d["spec"]["selector"].get("matchLabels"),
               "NetworkPolicy": lambda d: d["spec"]["podSelector"].get("matchLabels")}
    for kind, get in selects.items():
        for d in by_kind(docs, kind):
            if get(d) is None and kind == "Service":
                continue  # no selector: endpoints of its own, or an ExternalName
            which = [w for w, labels in pods.items() if matches(get(d), labels)]
            if len(which) != 1:
                problems.append(f"{kind} {d['metadata']['name']}: selects the pods of "
                                f"{len(which)} workloads ({', '.join(which) or 'none'}), not 1")
    services = {d["metadata"]["name"]: d for d in by_kind(docs, "Service")}
    for d in by_kind(docs, "StatefulSet"):
        svc = services.get(d["spec"].get("serviceName"))
        if svc is None:
            problems.append(f"StatefulSet {d['metadata']['name']}: no Service "
                            f"{d['spec'].get('serviceName')} (its serviceName)")
        elif not matches(svc["spec"].get("selector"), d["spec"]["template"]["metadata"]["labels"]):
            problems.append(f"StatefulSet {d['metadata']['name']}: its Service "
                            f"{svc['metadata']['name']} does not select its pods")
    deps = by_kind(docs, "Deployment")
    for d in by_kind(docs, "HorizontalPodAutoscaler"):
        t = d["spec"]["scaleTargetRef"]
        if not any((t["kind"], t["name"]) == ("Deployment", x["metadata"]["name"]) for x in deps):
            problems.append(f"HorizontalPodAutoscaler targets {t['kind']} {t['name']}")
    return problems


def check_pod(w, names):
    """A workload's pod template: what every pod of these manifests must do."""
    problems = []
    what = f"{w['kind']} {w['metadata']['name']}"
    spec = w["spec"]["template"]["spec"]
    if not spec.get("securityContext", {}).get("runAsNonRoot"):
        problems.append(f"{what}: the pod does not require runAsNonRoot")
    vols = {v["name"] for v in spec.get("volumes", [])}
    vols |= {t["metadata"]["name"] for t in w["spec"].get("volumeClaimTemplates", [])}
    for vol in spec.get("volumes", []):
        claim = vol.get("persistentVolumeClaim", {}).get("claimName")
        if claim and claim not in names["PersistentVolumeClaim"]:
            problems.append(f"{what}: volume {vol['name']}: no PersistentVolumeClaim {claim}")
    for c in spec["containers"]:
        who = f"{what}: {c['name']}"
        sc = c.get("securityContext", {})
        if not (sc.get("readOnlyRootFilesystem")
                and "ALL" in sc.get("capabilities", {}).get("drop", [])
                and sc.get("allowPrivilegeEscalation") is False):
            problems.append(f"{who}: needs a read-only root, drop ALL, no privilege escalation")
        res = c.get("resources", {})
        for part in ("requests", "limits"):
            if not {"cpu", "memory"} <= set(res.get(part, {})):
                problems.append(f"{who}: resources.{part} needs cpu and memory")
        ports = {p.get("name"): p["containerPort"] for p in c.get("ports", [])}
        for probe in ("readinessProbe", "livenessProbe"):
            if probe not in c:
                problems.append(f"{who}: no {probe}")
                continue
            port = c[probe].get("httpGet", {}).get("port")
            if "httpGet" in c[probe] and port not in ports and port not in ports.values():
                problems.append(f"{who}: {probe} port {port} is no container port")
        for m in c.get("volumeMounts", []):
            if m["name"] not in vols:
                problems.append(f"{who}: volumeMount {m['name']} names no volume")
        for ref in c.get("envFrom", []):
            cm = ref.get("configMapRef", {}).get("name")
            if cm and cm not in names["ConfigMap"]:
                problems.append(f"{who}: no ConfigMap {cm}")
        for e in c.get("env", []):
            ref = e.get("valueFrom", {}).get("secretKeyRef")
            if ref and ref.get("key") not in names["Secret"].get(ref.get("name"), {}):
                problems.append(f"{who}: no Secret {ref.get('name')} with key {ref.get('key')}")
    return problems


def environment(c, names):
    """A container's variables: name -> (source, value); source is configmap, value, secret
    (value: (name, key)) or field (value: the fieldPath)."""
    env = {}
    for ref in c.get("envFrom", []):
        cm = ref.get("configMapRef", {}).get("name")
        for k, v in names["ConfigMap"].get(cm, {}).items():
            env[k] = ("configmap", v)
    for e in c.get("env", []):
        src = e.get("valueFrom", {})
        if "secretKeyRef" in src:
            env[e["name"]] = ("secret", (src["secretKeyRef"].get("name"),
                                         src["secretKeyRef"].get("key")))
        elif "fieldRef" in src:
            env[e["name"]] = ("field", src["fieldRef"].get("fieldPath"))
        elif src:
            env[e["name"]] = ("other", None)
        else:
            env[e["name"]] = ("value", e.get("value", ""))
    return env


def check_sdfd(dep, names):
    """The sdfd Deployment's container(s) against the rest; returns problems."""
    problems = []
    spec = dep["spec"]["template"]["spec"]
    annotations = dep["spec"]["template"]["metadata"].get("annotations", {})
    for vol in spec.get("volumes", []):
        claim = names["PersistentVolumeClaim"].get(
            vol.get("persistentVolumeClaim", {}).get("claimName"), {})
        template = vol.get("ephemeral", {}).get("volumeClaimTemplate", {})
        modes = (claim.get("spec", {}).get("accessModes", [])
                 + template.get("spec", {}).get("accessModes", []))
        if "ReadWriteMany" in modes:
            problems.append(f"volume {vol['name']}: a ReadWriteMany claim; the replicas share "
                            f"the catalog (SDFD_CATALOG), no file system")
    for c in spec["containers"]:
        env = environment(c, names)
        plain = {k: v for k, (source, v) in env.items() if source in ("configmap", "value")}
        ports = {p.get("name"): p["containerPort"] for p in c.get("ports", [])}
        if str(ports.get("http")) != annotations.get("prometheus.io/port"):
            problems.append("the prometheus.io/port annotation is not the http port")
        cmd = c.get("lifecycle", {}).get("preStop", {}).get("exec", {}).get("command", [])
        sleep = int(cmd[1]) if len(cmd) == 2 and cmd[0] == "sleep" else 0
        drain = int(plain.get("SDFD_DRAIN_SECONDS", 30))
        if sleep == 0:
            problems.append(f"{c['name']}: no preStop sleep")
        if spec.get("terminationGracePeriodSeconds", 30) <= sleep + drain:
            problems.append(f"terminationGracePeriodSeconds is not above preStop {sleep} s + "
                            f"drain {drain} s")
        res = c.get("resources", {})
        cpu = str(res.get("limits", {}).get("cpu", "0"))
        cpus = int(cpu[:-1]) / 1000 if cpu.endswith("m") else float(cpu)
        if int(plain.get("SDFD_THREADS", 0)) == 0 or int(plain["SDFD_THREADS"]) > max(cpus, 1):
            problems.append("SDFD_THREADS must be set, at most the CPU limit")
        problems += check_catalog(c, env, names)
        problems += check_cache(c, env, spec)
        problems += check_memory(c, plain)
    return problems


def check_catalog(c, env, names):
    problems = []
    source, value = env.get("SDFD_CATALOG", (None, None))
    if source is None:
        problems.append(f"{c['name']}: SDFD_CATALOG is not set (the replicas would share no "
                        f"meshes, volumes or jobs)")
    elif source != "secret":
        problems.append(f"{c['name']}: SDFD_CATALOG must come from a Secret (secretKeyRef): "
                        f"its URI holds the password")
    else:
        uri = names["Secret"].get(value[0], {}).get(value[1])
        if uri:
            problems += check_catalog_uri(uri, names)
    if env.get("SDFD_REPLICA_ID") != ("field", "metadata.name"):
        problems.append(f"{c['name']}: SDFD_REPLICA_ID must be the pod's name (fieldRef "
                        f"metadata.name), which jobs show as their owner")
    return problems


def check_cache(c, env, spec):
    """With the catalog, SDFD_DATA_DIR holds local copies of its bytes: each replica's own."""
    source, value = env.get("SDFD_DATA_DIR", (None, None))
    if source is None:
        return []
    own = {v["name"] for v in spec.get("volumes", []) if "emptyDir" in v}
    mounts = {m["mountPath"]: m["name"] for m in c.get("volumeMounts", [])}
    if source != "value" or mounts.get(value) not in own:
        return [f"{c['name']}: SDFD_DATA_DIR {value} is not the mount of an emptyDir (with the "
                f"catalog it holds the replica's own copies of its bytes)"]
    return []


def check_catalog_uri(uri, names):
    """A libpq URI naming a Service of the build: its port, and the PostgreSQL behind it."""
    if not re.match(r"postgres(ql)?://", uri):
        return []
    u = urllib.parse.urlsplit(uri)
    host = u.hostname or ""
    m = re.fullmatch(r"([a-z0-9-]+)(\.[a-z0-9-]+\.svc(\.cluster\.local)?)?", host)
    if not m:
        return []  # outside the cluster
    svc = names["Service"].get(m.group(1))
    if svc is None:
        return [f"the catalog URI names host {host}, and there is no Service {m.group(1)}"]
    port = u.port or 5432
    if port not in [p.get("port") for p in svc["spec"].get("ports", [])]:
        return [f"the catalog URI names port {port}, which Service {m.group(1)} has not"]
    problems = []
    for w in names["workloads"]:
        labels = w["spec"]["template"]["metadata"]["labels"]
        if not matches(svc["spec"].get("selector"), labels):
            continue
        # the pod's port: a NetworkPolicy names that, by number or name
        target = next(p.get("targetPort", port) for p in svc["spec"]["ports"]
                      if p.get("port") == port)
        pod_ports = {target}
        for c in w["spec"]["template"]["spec"]["containers"]:
            pod_ports |= {cp.get(k) for cp in c.get("ports", []) for k in ("name", "containerPort")
                          if target in (cp.get("name"), cp.get("containerPort"))}
        for policy in names["NetworkPolicy"]:
            if (matches(policy["spec"]["podSelector"].get("matchLabels"), labels)
                    and not admits(policy, names["sdfd pods"], pod_ports)):
                problems.append(f"NetworkPolicy {policy['metadata']['name']}: does not let the "
                                f"sdfd pods reach {w['kind']} {w['metadata']['name']} on {port}")
        for c in w["spec"]["template"]["spec"]["containers"]:
            env = environment(c, names)
            if env.get("POSTGRES_PASSWORD", (None,))[0] != "secret":
                continue
            sname, skey = env["POSTGRES_PASSWORD"][1]
            want = {"user": env.get("POSTGRES_USER", ("value", "postgres"))[1]}
            want["database"] = env.get("POSTGRES_DB", ("value", want["user"]))[1]
            want["password"] = names["Secret"].get(sname, {}).get(skey)
            got = {"user": urllib.parse.unquote(u.username or ""),
                   "password": urllib.parse.unquote(u.password or ""),
                   "database": urllib.parse.unquote(u.path.lstrip("/"))}
            for k in ("user", "database", "password"):
                if got[k] != want[k]:
                    shown = "" if k == "password" else f" {got[k]!r}, not {want[k]!r}"
                    problems.append(f"the catalog URI's {k} is not that of {w['kind']} "
                                    f"{w['metadata']['name']}{shown}")
    return problems


def admits(policy, labels, pod_ports):
    """Does a NetworkPolicy let pods of these labels in on a port (number or name) of these?"""
    if "Ingress" not in policy["spec"].get("policyTypes", ["Ingress"]):
        return True
    for rule in policy["spec"].get("ingress", []):
        peers = rule.get("from", [])
        ports = [p.get("port") for p in rule.get("ports", [])]
        if ((not peers or any(matches(p.get("podSelector", {}).get("matchLabels"), labels)
                              for p in peers))
                and (not ports or pod_ports & set(ports))):
            return True
    return False


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
    """(problems, files read): the build of directory's kustomization, checked."""
    b = Build()
    docs = b.build(os.path.normpath(directory), [])
    problems = b.problems
    names = {"ConfigMap": {d["metadata"]["name"]: d.get("data", {})
                           for d in by_kind(docs, "ConfigMap")},
             "Secret": {d["metadata"]["name"]: secret_values(d) for d in by_kind(docs, "Secret")},
             "PersistentVolumeClaim": {d["metadata"]["name"]: d
                                       for d in by_kind(docs, "PersistentVolumeClaim")},
             "Service": {d["metadata"]["name"]: d for d in by_kind(docs, "Service")},
             "NetworkPolicy": by_kind(docs, "NetworkPolicy"),
             "workloads": [d for kind in WORKLOADS for d in by_kind(docs, kind)]}
    deps = by_kind(docs, "Deployment")
    names["sdfd pods"] = deps[0]["spec"]["template"]["metadata"]["labels"] if deps else {}
    problems += check_selectors(docs)
    for w in names["workloads"]:
        problems += check_pod(w, names)
    if len(deps) != 1:
        problems.append(f"expected one Deployment (sdfd), found {len(deps)}")
    else:
        problems += check_sdfd(deps[0], names)
    return problems, b.files


def main(argv):
    if len(argv) == 2 and argv[0] == "--kustomize":
        problems, files = check_kustomize(argv[1])
        problems = check_fields(files) + problems
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
