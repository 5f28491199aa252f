// Runs the Khronos glTF-Validator (npm gltf-validator, installed into .venv/node_modules by ./run tests) on one
// .glb or .gltf file and prints its report as JSON: node tests/gltf_validator.js FILE
const fs = require("fs");
const path = require("path");
const validator = require(path.join(__dirname, "..", ".venv", "node_modules", "gltf-validator"));

const file = process.argv[2];
const data = new Uint8Array(fs.readFileSync(file));
validator
    .validateBytes(data, {
        uri: path.basename(file),
        maxIssues: 0,
        externalResourceFunction: (uri) =>
            new Promise((resolve, reject) => {
                fs.readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)), (error, bytes) =>
                    error ? reject(error.toString()) : resolve(new Uint8Array(bytes)));
            }),
    })
    .then((report) => process.stdout.write(JSON.stringify(report)))
    .catch((error) => {
        process.stderr.write(String(error) + "\n");
        process.exit(1);
    });
