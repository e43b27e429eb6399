// Validates an OpenAPI document against the OpenAPI 3.x JSON schemas with
// @seriousme/openapi-schema-validator (independent of the server's code):
//   node validate.mjs FILE   -> exit 0 and "valid (3.1)", or exit 1 and the errors
import { Validator } from "@seriousme/openapi-schema-validator";

const file = process.argv[2];
if (!file) {
  console.error("usage: node validate.mjs openapi.json");
  process.exit(2);
}
const validator = new Validator();
const res = await validator.validate(file);
if (!res.valid) {
  console.error(JSON.stringify(res.errors, null, 2));
  process.exit(1);
}
console.log(`valid (${validator.version})`);
