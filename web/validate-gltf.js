// Validate glTF files with the Khronos glTF Validator (npm gltf-validator).
// Usage: node web/validate-gltf.js file.glb [...]
// Prints one line per file (errors, warnings, infos, hints) and every error and warning;
// exits 1 if any file has an error or a warning.
const fs = require('fs');
const validator = require('gltf-validator');

async function main() {
  const files = process.argv.slice(2);
  if (files.length === 0) {
    console.error('usage: node web/validate-gltf.js file.glb [...]');
    process.exit(2);
  }
  let bad = false;
  for (const f of files) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(f)), {maxIssues: 1000});
    const i = report.issues;
    console.log(`${f}: ${i.numErrors} errors, ${i.numWarnings} warnings, ${i.numInfos} infos, ${i.numHints} hints ` +
                `(validator ${report.validatorVersion})`);
    for (const m of i.messages)
      if (m.severity <= 1) console.log(`  ${m.severity === 0 ? 'error' : 'warning'} ${m.code} at ${m.pointer}: ${m.message}`);
    if (i.numErrors > 0 || i.numWarnings > 0) bad = true;
  }
  process.exit(bad ? 1 : 0);
}
main().catch(e => { console.error(e.message || e); process.exit(1); });
