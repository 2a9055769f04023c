// Rewrites a recorded run in an order rosbag2 may record the live cell in: messages as they
// arrive, each frame's image ahead of that frame's simulator status and camera pose (cellsim
// publishes the status first, but three topics on two transports arrive in any order). Each
// status and pose is moved to just after the image that carries its stamp.
// `servo replay --expect-identical` must reproduce the twists of that recording too.
//
//   node arrival_order.mjs MODULES_DIR IN.mcap OUT.mcap   (prints how many it moved)
import { createRequire } from "node:module";
import { readFileSync, writeFileSync } from "node:fs";
import path from "node:path";

const [modulesDir, input, output] = process.argv.slice(2);
if (!modulesDir || !input || !output) {
  console.error("usage: arrival_order.mjs MODULES_DIR IN.mcap OUT.mcap");
  process.exit(2);
}
const require = createRequire(path.resolve(modulesDir, "package.json"));
const { McapStreamReader, McapWriter } = require("@mcap/core");

const stream = new McapStreamReader({ validateCrcs: true });
stream.append(new Uint8Array(readFileSync(input)));
let header;
const schemas = [], channels = [], messages = [];
for (let r; (r = stream.nextRecord()); ) {
  if (r.type === "Header") header = r;
  else if (r.type === "Schema") schemas.push(r);
  else if (r.type === "Channel") channels.push(r);
  else if (r.type === "Message") messages.push(r);
}
const topicOf = new Map(channels.map((c) => [c.id, c.topic]));
const is = (m, t) => topicOf.get(m.channelId).endsWith(t);
// every message here begins with its header: 4 bytes of CDR encapsulation, then the stamp
const stamp = (m) => Buffer.from(m.data.subarray(4, 12)).toString("hex");

const moved = messages.filter((m) => is(m, "/sim/status") || is(m, "/sim/camera_pose"));
const rest = messages.filter((m) => !(is(m, "/sim/status") || is(m, "/sim/camera_pose")));
const byStamp = new Map();
for (const m of moved) {
  if (!byStamp.has(stamp(m))) byStamp.set(stamp(m), []);
  byStamp.get(stamp(m)).push(m);
}
const out = [];
let count = 0;
for (const m of rest) {
  out.push(m);
  if (!is(m, "/camera/image_raw")) continue;
  const after = byStamp.get(stamp(m)) ?? [];
  byStamp.delete(stamp(m));
  for (const x of after) out.push({ ...x, logTime: m.logTime + 1n, publishTime: m.logTime + 1n });
  count += after.length;
}
for (const left of byStamp.values()) out.push(...left);  // statuses of no recorded image (NOTICE, ENDED)
out.sort((a, b) => (a.logTime < b.logTime ? -1 : a.logTime > b.logTime ? 1 : 0));

const parts = [];
let size = 0n;
const writable = {
  write: async (b) => { parts.push(new Uint8Array(b)); size += BigInt(b.length); },
  position: () => size,
};
const writer = new McapWriter({ writable, useChunks: true });
await writer.start({ profile: header.profile, library: "arrival_order.mjs" });
const schemaIds = new Map(), channelIds = new Map();
for (const s of schemas) schemaIds.set(s.id, await writer.registerSchema({ name: s.name, encoding: s.encoding, data: s.data }));
for (const c of channels)
  channelIds.set(c.id, await writer.registerChannel({
    topic: c.topic, messageEncoding: c.messageEncoding, schemaId: schemaIds.get(c.schemaId) ?? 0, metadata: c.metadata,
  }));
for (const m of out) await writer.addMessage({ ...m, channelId: channelIds.get(m.channelId) });
await writer.end();
writeFileSync(output, Buffer.concat(parts));
console.log(`arrival_order: ${count} statuses and poses moved after their images`);
