// Validate a .glb with the Khronos glTF validator; print its JSON report on stdout.
// Usage: node tests/js/validate_gltf.js FILE.glb   (exit 0 when it ran, whatever it found)
"use strict";
const fs = require("fs");
const validator = require("gltf-validator");

const file = process.argv[2];
const data = new Uint8Array(fs.readFileSync(file));
validator.validateBytes(data, { uri: file, maxIssues: 100 })
  .then((report) => { process.stdout.write(JSON.stringify(report, null, 1)); })
  .catch((error) => { console.error(`validate_gltf: ${file}: ${error}`); process.exit(3); });
