// Validates .glb and .gltf files with the Khronos glTF-Validator (npm gltf-validator); a
// .gltf's external buffers are read from beside it.
// usage: node gltf_validate.mjs <node_modules dir> <file.glb|file.gltf>...
// Prints the issues and exits non-zero when any file has an error.
import fs from 'node:fs';
import path from 'node:path';
import { createRequire } from 'node:module';

const [modules, ...files] = process.argv.slice(2);
const require = createRequire(modules + '/');
const validator = require('gltf-validator');
let failed = 0;
for (const file of files) {
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    maxIssues: 100,
    uri: file,
    externalResourceFunction: (uri) =>
      file.endsWith('.gltf')
        ? Promise.resolve(new Uint8Array(fs.readFileSync(path.join(path.dirname(file), decodeURIComponent(uri)))))
        : Promise.reject(new Error('no external resources')),
  });
  const { numErrors, numWarnings, numInfos, messages } = report.issues;
  console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
  for (const m of messages) console.log(`  [${m.severity}] ${m.code} ${m.pointer ?? ''}: ${m.message}`);
  if (numErrors > 0) failed += 1;
}
process.exit(failed ? 1 : 0);
