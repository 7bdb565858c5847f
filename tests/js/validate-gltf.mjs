// Validate a glTF/GLB file with the Khronos glTF validator; prints its report as JSON.
// node validate-gltf.mjs FILE.glb  (run with Playwright's bundled node by tests/test_glb.py)
import fs from 'node:fs';
import * as validator from './node_modules/gltf-validator/module.mjs';

const data = new Uint8Array(fs.readFileSync(process.argv[2]));
const report = await validator.validateBytes(data, {maxIssues: 100});
console.log(JSON.stringify(report));
