// An independent reader for the cell's recordings: Foxglove's @mcap/core (the library the
// Foxglove app reads MCAP with), @foxglove/rosmsg (its .msg parser) and
// @foxglove/rosmsg2-serialization (its CDR reader), pinned by package-lock.json and
// installed by bin/setup into build/mcap-check.
//
//   node check_mcap.mjs MODULES_DIR FILE.mcap ['{"/topic": count, ...}']
//
// Reads FILE twice, as a stream (every record, every chunk CRC) and through its index (the
// summary, its CRC, the chunk indexes, as a seeking reader does); checks the ROS 2 profile
// (ros2msg schemas that parse as ROS 2 .msg text, cdr channels with offered_qos_profiles
// and a RIHS01 topic_type_hash) and decodes every message with its schema, which must use
// up the message's bytes. Prints one JSON line of what it found; exits 1 naming the first
// thing that is wrong, and when the counts differ from the expected ones given.
import { createRequire } from "node:module";
import { readFileSync } from "node:fs";
import path from "node:path";

const [modulesDir, file, expectedJson] = process.argv.slice(2);
if (!modulesDir || !file) {
  console.error("usage: check_mcap.mjs MODULES_DIR FILE.mcap [EXPECTED_COUNTS_JSON]");
  process.exit(2);
}
const require = createRequire(path.resolve(modulesDir, "package.json"));
const { McapIndexedReader, McapStreamReader } = require("@mcap/core");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");

function fail(what) {
  console.error(`check_mcap: ${file}: ${what}`);
  process.exit(1);
}

const bytes = new Uint8Array(readFileSync(file));

// 1. as a stream: every record in order, chunk CRCs validated
const stream = new McapStreamReader({ validateCrcs: true });
stream.append(bytes);
const records = {};
const streamCounts = new Map();
const channelsById = new Map();
let header;
for (let r; (r = stream.nextRecord()); ) {
  records[r.type] = (records[r.type] ?? 0) + 1;
  if (r.type === "Header") header = r;
  if (r.type === "Channel") channelsById.set(r.id, r);
  if (r.type === "Message") {
    const topic = channelsById.get(r.channelId).topic;
    streamCounts.set(topic, (streamCounts.get(topic) ?? 0) + 1);
  }
}
if (!stream.done()) fail(`the stream reader did not reach the footer (${stream.bytesRemaining()} bytes left)`);
if (header?.profile !== "ros2") fail(`header profile is '${header?.profile}', not 'ros2'`);

// 2. through the index, as a seeking reader does
const readable = {
  size: async () => BigInt(bytes.length),
  read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
};
const indexed = await McapIndexedReader.Initialize({ readable });
if (!indexed.statistics) fail("no statistics record in the summary");
if (indexed.chunkIndexes.length === 0) fail("no chunk index in the summary");
if (indexed.chunkIndexes.length !== indexed.statistics.chunkCount)
  fail(`${indexed.chunkIndexes.length} chunk indexes, statistics say ${indexed.statistics.chunkCount} chunks`);

// 3. the ROS 2 profile: schemas that parse, channels with their metadata
const readers = new Map();
for (const [id, schema] of indexed.schemasById) {
  if (schema.encoding !== "ros2msg") fail(`schema ${schema.name}: encoding '${schema.encoding}', not ros2msg`);
  if (!/^[a-z0-9_]+\/msg\/[A-Za-z0-9]+$/.test(schema.name)) fail(`schema name '${schema.name}' is not pkg/msg/Type`);
  let definitions;
  try {
    definitions = parse(new TextDecoder().decode(schema.data), { ros2: true });
  } catch (e) {
    fail(`schema ${schema.name} does not parse as ROS 2 .msg text: ${e.message}`);
  }
  readers.set(id, new MessageReader(definitions));
}
for (const channel of indexed.channelsById.values()) {
  if (channel.messageEncoding !== "cdr") fail(`channel ${channel.topic}: encoding '${channel.messageEncoding}', not cdr`);
  if (!channel.metadata.get("offered_qos_profiles")?.startsWith("- history:"))
    fail(`channel ${channel.topic}: no offered_qos_profiles`);
  if (!/^RIHS01_[0-9a-f]{64}$/.test(channel.metadata.get("topic_type_hash") ?? ""))
    fail(`channel ${channel.topic}: no RIHS01 topic_type_hash`);
  if (!readers.has(channel.schemaId)) fail(`channel ${channel.topic}: schema ${channel.schemaId} is not in the summary`);
}

// 4. every message through the index, decoded with its schema
const counts = {};
let messages = 0;
let lastLogTime = -1n;
for await (const m of indexed.readMessages({ validateCrcs: true })) {
  const channel = indexed.channelsById.get(m.channelId);
  if (m.logTime < lastLogTime) fail(`messages out of log-time order at ${channel.topic}`);
  lastLogTime = m.logTime;
  const reader = readers.get(channel.schemaId);
  try {
    reader.readMessage(m.data);
  } catch (e) {
    fail(`${channel.topic} message ${m.sequence} does not decode with its schema: ${e.message}`);
  }
  if (reader.lastReadHadTrailingBytes())
    fail(`${channel.topic} message ${m.sequence}: ${m.data.length - reader.lastReadByteLength()} bytes left after decoding`);
  counts[channel.topic] = (counts[channel.topic] ?? 0) + 1;
  ++messages;
}
if (BigInt(messages) !== indexed.statistics.messageCount)
  fail(`${messages} messages through the index, statistics say ${indexed.statistics.messageCount}`);
for (const [id, n] of indexed.statistics.channelMessageCounts) {
  const topic = indexed.channelsById.get(id).topic;
  if (BigInt(counts[topic] ?? 0) !== n) fail(`${topic}: ${counts[topic] ?? 0} messages, statistics say ${n}`);
  if ((streamCounts.get(topic) ?? 0) !== (counts[topic] ?? 0)) fail(`${topic}: the stream and the index disagree`);
}
if (expectedJson) {
  const expected = JSON.parse(expectedJson);
  for (const topic of new Set([...Object.keys(expected), ...Object.keys(counts)]))
    if ((expected[topic] ?? 0) !== (counts[topic] ?? 0))
      fail(`${topic}: ${counts[topic] ?? 0} messages read, the recorder reported ${expected[topic] ?? 0}`);
}
console.log(JSON.stringify({ profile: header.profile, library: header.library, messages, chunks: indexed.chunkIndexes.length,
  schemas: [...indexed.schemasById.values()].map((s) => s.name).sort(), records, topics: counts }));
