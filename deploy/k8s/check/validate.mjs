// validate.mjs - checks Kubernetes manifests offline against the API's schemas (the npm
// package kubernetes-models: field types, required fields, formats). Every document of every
// file given must be a kind it knows and valid; exit 1 otherwise, naming file, kind, name and
// what is wrong; kustomizations and components (kustomize.config.k8s.io) are skipped.
// deploy/test.sh runs it on the manifests of deploy/k8s/*/ and deploy/podman/.
//
//   node deploy/k8s/check/validate.mjs FILE.yaml...
import { readFileSync } from "node:fs";
import { parseAllDocuments } from "yaml";

// apps/v1 -> kubernetes-models/apps/v1, v1 (the core group) -> kubernetes-models/v1
function modulePath(apiVersion, kind) {
  return `kubernetes-models/${apiVersion}/${kind}`;
}

async function check(file) {
  let problems = 0;
  for (const doc of parseAllDocuments(readFileSync(file, "utf8"))) {
    if (doc.errors.length) {
      console.log(`${file}: YAML: ${doc.errors[0].message}`);
      problems++;
      continue;
    }
    const obj = doc.toJS();
    if (obj === null) continue;
    const what = `${file}: ${obj.kind}/${obj.metadata?.name}`;
    if (obj.apiVersion?.startsWith("kustomize.config.k8s.io/")) continue; // not an API object
    let Model;
    try {
      Model = (await import(modulePath(obj.apiVersion, obj.kind)))[obj.kind];
    } catch {
      console.log(`${what}: unknown apiVersion/kind ${obj.apiVersion} ${obj.kind}`);
      problems++;
      continue;
    }
    try {
      new Model(obj).validate();
    } catch (e) {
      console.log(`${what}: ${e.message}`);
      problems++;
    }
  }
  return problems;
}

let problems = 0;
for (const file of process.argv.slice(2)) problems += await check(file);
if (process.argv.length < 3) {
  console.log("usage: node validate.mjs FILE.yaml...");
  problems = 1;
}
process.exit(problems ? 1 : 0);
