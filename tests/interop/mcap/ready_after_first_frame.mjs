// Rewrites a recorded bin/demo run as the other order of a race the two services run at
// start-up: the servo's "ready" twist (stamp 0, zero twist), sent as the servo starts, heard
// by cellsim's recorder only after the first frame went out. A recording that holds it
// elsewhere has it moved; one without it (the servo started first, before the recorder
// listened) gets one, made from the first recorded twist's bytes with its stamp and twist
// zeroed. `servo replay --expect-identical` must reproduce that recording too.
//
//   node ready_after_first_frame.mjs MODULES_DIR IN.mcap OUT.mcap
import { readRecords, scriptArgs, stampIsZero, topicTest, writeRecords } from "./mcap_records.mjs";

const { args, fail } = scriptArgs("ready_after_first_frame", "MODULES_DIR IN.mcap OUT.mcap", (a) => a.length === 3);
const [modulesDir, input, output] = args;
const records = readRecords(modulesDir, input);
const { header, messages } = records;
if (!header) fail("no header");
const on = topicTest(records);
const isTwist = (m) => on(m, "/servo/cmd_twist");
const isImage = (m) => on(m, "/camera/image_raw");
// (a TwistStamped's 6 doubles are its last 48 bytes)

if (!messages.some(isImage)) fail("no image");
const firstTwist = messages.findIndex(isTwist);
if (firstTwist < 0) fail("no twist");
// the first frame may carry stamp 0 too: the ready twist is the one stamp-0 twist more than
// stamp-0 frames
const zeroTwists = messages.filter((m) => isTwist(m) && stampIsZero(m)).length;
const zeroImages = messages.filter((m) => isImage(m) && stampIsZero(m)).length;
const synthesised = zeroTwists <= zeroImages;
let ready;
if (!synthesised) {
  [ready] = messages.splice(messages.findIndex((m) => isTwist(m) && stampIsZero(m)), 1);
} else {
  const data = new Uint8Array(messages[firstTwist].data);
  data.fill(0, 4, 12);
  data.fill(0, data.length - 48);
  ready = { ...messages[firstTwist], data, sequence: 0 };
}
const at = messages.findIndex(isImage) + 1;
ready = { ...ready, logTime: messages[at - 1].logTime + 1n, publishTime: messages[at - 1].logTime + 1n };
messages.splice(at, 0, ready);

await writeRecords(modulesDir, output, records, messages, "ready_after_first_frame.mjs");
console.log(`ready twist ${synthesised ? "added" : "moved"} after the first frame (message ${at} of ${messages.length})`);
