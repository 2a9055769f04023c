// Reading a recording's records and writing them back, for the scripts that rewrite a recorded
// run into an order the live cell can produce (ready_after_first_frame.mjs, arrival_order.mjs,
// stopped_before_its_image.mjs, lost_notice.mjs).
import { createRequire } from "node:module";
import { readFileSync, writeFileSync } from "node:fs";
import path from "node:path";

// A script's arguments after `node SCRIPT`, checked: its usage line and exit 2 unless `valid`
// says they are right; and fail(what), one line naming the script and its input (the second
// argument), exit 1.
export function scriptArgs(script, usage, valid) {
  const args = process.argv.slice(2);
  if (!valid(args)) {
    console.error(`usage: ${script}.mjs ${usage}`);
    process.exit(2);
  }
  const fail = (what) => {
    console.error(`${script}: ${args[1]}: ${what}`);
    process.exit(1);
  };
  return { args, fail };
}

// on(m, "/servo/cmd_twist"): whether the message is on that topic, under any namespace
export function topicTest({ channels }) {
  const topicOf = new Map(channels.map((c) => [c.id, c.topic]));
  return (m, topic) => topicOf.get(m.channelId).endsWith(topic);
}

// Every message of the cell begins with its header: 4 bytes of CDR encapsulation, then the
// stamp (sec, nanosec). The stamp's 8 bytes as a key, and whether they are zero.
export const stampKey = (m) => Buffer.from(m.data.subarray(4, 12)).toString("hex");
export const stampIsZero = (m) => m.data.subarray(4, 12).every((b) => b === 0);

// The header, schemas, channels and messages of an MCAP file, read as a stream (CRCs checked).
export function readRecords(modulesDir, file) {
  const require = createRequire(path.resolve(modulesDir, "package.json"));
  const { McapStreamReader } = require("@mcap/core");
  const stream = new McapStreamReader({ validateCrcs: true });
  stream.append(new Uint8Array(readFileSync(file)));
  const out = { header: undefined, schemas: [], channels: [], messages: [] };
  for (let r; (r = stream.nextRecord()); ) {
    if (r.type === "Header") out.header = r;
    else if (r.type === "Schema") out.schemas.push(r);
    else if (r.type === "Channel") out.channels.push(r);
    else if (r.type === "Message") out.messages.push(r);
  }
  return out;
}

// A new chunked MCAP file of those records, `messages` in the order given, then the metadata
// records given ({name, metadata: Map}).
export async function writeRecords(modulesDir, file, { header, schemas, channels }, messages, library, metadata = []) {
  const require = createRequire(path.resolve(modulesDir, "package.json"));
  const { McapWriter } = require("@mcap/core");
  const parts = [];
  let size = 0n;
  const writable = {
    write: async (b) => { parts.push(new Uint8Array(b)); size += BigInt(b.length); },
    position: () => size,
  };
  const writer = new McapWriter({ writable, useChunks: true });
  await writer.start({ profile: header.profile, library });
  const schemaIds = new Map(), channelIds = new Map();
  for (const s of schemas) schemaIds.set(s.id, await writer.registerSchema({ name: s.name, encoding: s.encoding, data: s.data }));
  for (const c of channels)
    channelIds.set(c.id, await writer.registerChannel({
      topic: c.topic, messageEncoding: c.messageEncoding, schemaId: schemaIds.get(c.schemaId) ?? 0, metadata: c.metadata,
    }));
  for (const m of messages) await writer.addMessage({ ...m, channelId: channelIds.get(m.channelId) });
  for (const m of metadata) await writer.addMetadata(m);
  await writer.end();
  writeFileSync(file, Buffer.concat(parts));
}
