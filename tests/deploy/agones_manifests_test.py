#!/usr/bin/env python3
"""The Agones manifests in deploy/agones/ validate against Agones' published
CRD schemas (deploy/agones/schemas/, their source and licence in SOURCE.md)
with Debian's python3-jsonschema, strictly: an object schema that lists
properties accepts no other field (as kubectl's strict field validation
refuses unknown fields) unless it says x-kubernetes-preserve-unknown-fields.
Then what the schema cannot say: every manifest's door port is the
GameServer's port, health is on, resources are requested, the GPU fleet asks
for a GPU, the FleetAutoscaler buffers the Fleet that exists. And the test
can fail: a mutated manifest (an unknown field, a wrong type) is refused.
   agones_manifests_test.py SOURCE_DIR

The schemas were made from Agones' install/yaml/install.yaml with:
  for each CustomResourceDefinition of kind Fleet, FleetAutoscaler, GameServer:
    {"apiVersion": group + "/v1", "kind": kind,
     "openAPIV3Schema": spec.versions[name == v1].schema.openAPIV3Schema}
"""
import copy
import json
import os
import sys

import jsonschema
import yaml

src = sys.argv[1]
agones = os.path.join(src, "deploy", "agones")


def strict(schema):
    """A copy of a Kubernetes structural schema that refuses unknown fields."""
    if isinstance(schema, dict):
        out = {k: strict(v) for k, v in schema.items()}
        if ("properties" in schema and "additionalProperties" not in schema
                and not schema.get("x-kubernetes-preserve-unknown-fields")):
            out["additionalProperties"] = False
        return out
    if isinstance(schema, list):
        return [strict(v) for v in schema]
    return schema


schemas = {}
for name in ("fleet", "fleetautoscaler", "gameserver"):
    with open(os.path.join(agones, "schemas", name + ".v1.schema.json")) as f:
        s = json.load(f)
    schema = strict(s["openAPIV3Schema"])
    # The fields every Kubernetes object has, which a CRD's schema leaves out.
    schema["properties"].update({"apiVersion": {"enum": [s["apiVersion"]]},
                                 "kind": {"enum": [s["kind"]]}, "metadata": {"type": "object"}})
    schema["required"] = sorted(set(schema.get("required", [])) | {"apiVersion", "kind", "metadata"})
    jsonschema.Draft4Validator.check_schema(schema)
    schemas[(s["apiVersion"], s["kind"])] = jsonschema.Draft4Validator(schema)

failures = []


def errors_of(doc):
    key = (doc.get("apiVersion"), doc.get("kind"))
    if key not in schemas:
        return ["no Agones schema for %s %s" % key]
    return ["%s: %s" % ("/".join(map(str, e.absolute_path)), e.message)
            for e in schemas[key].iter_errors(doc)]


docs = {}
for file in sorted(os.listdir(agones)):
    if not file.endswith(".yaml"):
        continue
    with open(os.path.join(agones, file)) as f:
        doc = yaml.safe_load(f)
    docs[file] = doc
    errs = errors_of(doc)
    print("%s: %s %s: %s" % (file, doc["apiVersion"], doc["kind"],
                             "valid" if not errs else "%d errors" % len(errs)))
    failures += ["%s: %s" % (file, e) for e in errs[:10]]

expected = {"gameserver.yaml", "fleet.yaml", "fleet-gpu.yaml", "fleetautoscaler.yaml"}
if set(docs) != expected:
    failures.append("deploy/agones holds %s, expected %s" % (sorted(docs), sorted(expected)))


def check(cond, what):
    if not cond:
        failures.append(what)


fleets = {}
for file, doc in docs.items():
    if doc["kind"] == "FleetAutoscaler":
        continue
    gs = doc["spec"] if doc["kind"] == "GameServer" else doc["spec"]["template"]["spec"]
    if doc["kind"] == "Fleet":
        fleets[doc["metadata"]["name"]] = doc
    container = gs["template"]["spec"]["containers"][0]
    args = container["args"]
    listen = [a.split("=", 1)[1] for a in args if a.startswith("--ws-listen=")]
    check(len(listen) == 1, file + ": one --ws-listen")
    door_port = int(listen[0].rsplit(":", 1)[1]) if listen else None
    check([p["containerPort"] for p in gs["ports"]] == [door_port],
          file + ": the GameServer's one port is the door's %s" % door_port)
    check("--agones" in args, file + ": --agones")
    check(any(a.startswith("--ws-cert=") for a in args), file + ": the door off the pod uses TLS")
    check(not gs["health"].get("disabled", False) and gs["health"]["initialDelaySeconds"] > 0,
          file + ": health on, with an initial delay for the scene")
    req = container["resources"].get("requests", {})
    check("cpu" in req and "memory" in req, file + ": cpu and memory requested")
    check(container["securityContext"].get("readOnlyRootFilesystem") is True,
          file + ": read-only root file system")
    check(gs["template"]["spec"]["securityContext"].get("runAsNonRoot") is True,
          file + ": non-root")
    gpu = "nvidia.com/gpu" in container["resources"].get("limits", {})
    check(gpu == (file == "fleet-gpu.yaml"), file + ": a GPU exactly in the GPU variant")
    if gpu:
        check("--backend=gpu" in args and "--require-hardware" in args,
              file + ": --backend=gpu --require-hardware")
fa = docs.get("fleetautoscaler.yaml", {})
check(fa.get("spec", {}).get("policy", {}).get("type") == "Buffer", "autoscaler: buffer policy")
check(fa.get("spec", {}).get("fleetName") in fleets, "autoscaler: names an existing Fleet")

# The validation can fail: mutations are refused.
gs = copy.deepcopy(docs["gameserver.yaml"])
gs["spec"]["portz"] = []
check(any("portz" in e for e in errors_of(gs)), "an unknown field is refused")
gs = copy.deepcopy(docs["gameserver.yaml"])
gs["spec"]["health"]["periodSeconds"] = "five"
check(errors_of(gs), "a string for an integer is refused")
fa = copy.deepcopy(docs["fleetautoscaler.yaml"])
fa["spec"]["policy"]["buffer"]["maxReplicas"] = "many"
check(errors_of(fa), "a bad autoscaler is refused")

if failures:
    print("\n".join(failures), file=sys.stderr)
    sys.exit(1)
print("agones_manifests_test: passed")
