#!/usr/bin/env node
// Validates glTF files with Khronos's glTF-Validator (npm package
// gltf-validator) and exits 1 if any has an error, 0 if none, and 77 (the
// ctest SKIP_RETURN_CODE of the validator test) if the package is not
// installed. tools/setup.sh test installs it into tools/gltf-validator/.
//   node tools/validate_gltf.js FILE.glb [FILE.gltf ...]
'use strict';
const fs = require('fs');
const path = require('path');

let validator;
for (const where of [path.join(__dirname, 'gltf-validator', 'node_modules', 'gltf-validator'), 'gltf-validator']) {
  try {
    validator = require(where);
    break;
  } catch (e) {
    // try the next place
  }
}
if (!validator) {
  console.error('validate_gltf: the npm package gltf-validator is not installed ' +
                '(tools/setup.sh test installs it into tools/gltf-validator/)');
  process.exit(77);
}
const files = process.argv.slice(2);
if (files.length === 0) {
  console.error('usage: node tools/validate_gltf.js FILE.glb [FILE.gltf ...]');
  process.exit(2);
}

async function validate(file) {
  const bytes = new Uint8Array(fs.readFileSync(file));
  const report = await validator.validateBytes(bytes, {
    uri: file,
    maxIssues: 100,
    externalResourceFunction: (uri) => new Promise((resolve, reject) => {
      fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (err, data) => err ? reject(err) : resolve(new Uint8Array(data)));
    }),
  });
  const issues = report.issues;
  console.log(`${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings, ${issues.numInfos} infos, ` +
              `${issues.numHints} hints (glTF-Validator ${report.validatorVersion})`);
  for (const m of issues.messages) {
    const severity = ['error', 'warning', 'info', 'hint'][m.severity] || m.severity;
    console.log(`  ${severity}: ${m.code}: ${m.message} (${m.pointer || m.offset || ''})`);
  }
  return issues.numErrors;
}

(async () => {
  let errors = 0;
  for (const file of files) {
    try {
      errors += await validate(file);
    } catch (e) {
      console.log(`${file}: cannot validate: ${e}`);
      errors += 1;
    }
  }
  process.exit(errors > 0 ? 1 : 0);
})();
