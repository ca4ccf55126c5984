// Validate glTF files with Khronos' glTF-Validator (npm package gltf-validator):
//   node gltf_validate.js FILE...   -> one JSON report summary per line
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

async function main() {
  for (const file of process.argv.slice(2)) {
    const data = new Uint8Array(fs.readFileSync(file));
    const report = await validator.validateBytes(data, {
      uri: path.basename(file),
      maxIssues: 100,
      externalResourceFunction: (uri) =>
        new Promise((resolve, reject) => {
          fs.readFile(path.join(path.dirname(file), decodeURIComponent(uri)), (err, buf) =>
            err ? reject(err.toString()) : resolve(new Uint8Array(buf)));
        }),
    });
    const issues = report.issues;
    console.log(JSON.stringify({
      file, errors: issues.numErrors, warnings: issues.numWarnings,
      messages: issues.messages.map((m) => `${m.severity} ${m.code} ${m.pointer || ""} ${m.message}`),
    }));
  }
}
main().catch((e) => { console.error(String(e)); process.exit(1); });
