// A live viewer of the cell made of Foxglove's own libraries (@foxglove/ws-protocol's
// FoxgloveClient over the `ws` WebSocket, @foxglove/rosmsg and rosmsg2-serialization to read
// each message with the schema the server advertised): it connects to `cellsim serve
// --foxglove`, subscribes to the image, the annotations, /tf and the servo's status, decodes
// every message it receives, and waits for the servo to say CONVERGED.
//   node foxglove_client.mjs MODULES_DIR PORT [SECONDS]
import { createRequire } from "node:module";
import path from "node:path";

const [modulesDir, port, seconds = "120"] = process.argv.slice(2);
if (!modulesDir || !port) {
  console.error("usage: foxglove_client.mjs MODULES_DIR PORT [SECONDS]");
  process.exit(2);
}
const require = createRequire(path.resolve(modulesDir, "package.json"));
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");

function fail(what) {
  console.error(`foxglove_client: ${what}`);
  process.exit(1);
}
setTimeout(() => fail(`no CONVERGED within ${seconds} s; seen ${JSON.stringify(seen)}`), Number(seconds) * 1000);

const wanted = ["/camera/image_raw", "/servo/annotations", "/tf", "/servo/status"];
const seen = Object.fromEntries(wanted.map((t) => [t, 0]));
const bySubscription = new Map();  // subscription id -> {topic, reader}
const client = new FoxgloveClient({ ws: new WebSocket(`ws://127.0.0.1:${port}`, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]) });
client.on("error", (e) => fail(`connection: ${e.message ?? e}`));
client.on("advertise", (channels) => {
  for (const c of channels) {
    if (!wanted.includes(c.topic)) continue;
    if (c.encoding !== "cdr" || c.schemaEncoding !== "ros2msg") fail(`${c.topic}: encoding ${c.encoding}/${c.schemaEncoding}`);
    const reader = new MessageReader(parse(c.schema, { ros2: true }));
    bySubscription.set(client.subscribe(c.id), { topic: c.topic, reader });
  }
});
client.on("message", ({ subscriptionId, data }) => {
  const s = bySubscription.get(subscriptionId);
  if (!s) fail(`a message for subscription ${subscriptionId}, which was never made`);
  const m = s.reader.readMessage(new Uint8Array(data.buffer, data.byteOffset, data.byteLength));
  seen[s.topic] += 1;
  if (s.topic === "/camera/image_raw" && (m.width !== 640 || m.height !== 480 || m.data.length !== 640 * 480 * 3))
    fail(`image ${m.width} x ${m.height}, ${m.data.length} bytes`);
  if (s.topic === "/servo/annotations" && m.texts.length > 0 && !/^\d+,\d+$/.test(m.texts[0].text))
    fail(`an annotation's text '${m.texts[0].text}' is no "row,col" id`);
  if (s.topic === "/servo/annotations" && m.texts.length > 0) labelled = Math.max(labelled, m.texts.length);
  if (s.topic === "/servo/annotations" && m.points.length > 0) vectors = Math.max(vectors, m.points[0].points.length / 2);
  if (s.topic === "/tf" && m.transforms.length === 0) fail("a /tf message without transforms");
  if (s.topic === "/servo/status" && m.state === 3) done(m);
});
let labelled = 0, vectors = 0;

function done(status) {
  for (const t of wanted) if (seen[t] === 0) fail(`CONVERGED, but nothing received on ${t}: ${JSON.stringify(seen)}`);
  if (labelled === 0 || vectors === 0) fail(`annotations: at most ${labelled} ids, ${vectors} error vectors`);
  console.log(`foxglove_client: CONVERGED (|e| ${status.error_norm.toExponential(2)}); received ${JSON.stringify(seen)}; ` +
              `annotations with up to ${labelled} ids and ${vectors} error vectors`);
  process.exit(0);
}
