#!/usr/bin/env node
// Validates a glTF 2.0 file (.glb or .gltf) with the Khronos glTF validator (npm gltf-validator,
// installed next to this script by ./run) and prints its report as JSON on stdout.
// Exit status: 0 when the report has no errors, 1 when it has, 2 when the file could not be read
// or the validator could not run.
'use strict';
const fs = require('fs');
const path = require('path');

let validator;
try {
  validator = require(path.join(__dirname, 'node_modules', 'gltf-validator'));
} catch (e) {
  console.error('gltf-validator is not installed (run: npm ci --prefix tests/tools): ' + e.message);
  process.exit(2);
}

const file = process.argv[2];
if (!file) {
  console.error('usage: validate_gltf.js FILE.glb');
  process.exit(2);
}
let bytes;
try {
  bytes = fs.readFileSync(file);
} catch (e) {
  console.error(e.message);
  process.exit(2);
}
validator
    .validateBytes(new Uint8Array(bytes), {
      uri: path.basename(file),
      maxIssues: 100,
      externalResourceFunction: (uri) => new Promise((resolve, reject) => {
        fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)),
                    (err, data) => (err ? reject(err.toString()) : resolve(data)));
      }),
    })
    .then((report) => {
      console.log(JSON.stringify(report, null, 2));
      process.exit(report.issues.numErrors === 0 ? 0 : 1);
    }, (error) => {
      console.error(String(error));
      process.exit(2);
    });
