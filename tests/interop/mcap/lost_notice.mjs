// Rewrites a recorded bin/demo run as one where the live servo said LOST once: on a loaded
// machine no image reached it for --lost-ms after frame FRAME, and it published a LOST status
// and a zero twist at that frame's stamp, right after its answer. Those come from the servo's
// clock, not from an image: `servo replay --expect-identical` must count them apart.
//
//   node lost_notice.mjs MODULES_DIR IN.mcap OUT.mcap FRAME
import { readRecords, scriptArgs, stampKey as stamp, topicTest, writeRecords } from "./mcap_records.mjs";

const { args, fail } = scriptArgs("lost_notice", "MODULES_DIR IN.mcap OUT.mcap FRAME",
  (a) => a.length === 4 && Number(a[3]) >= 1);
const [modulesDir, input, output] = args;
const frame = Number(args[3]);
const records = readRecords(modulesDir, input);
const { messages } = records;
const on = topicTest(records);
// CDR, little endian: 4 bytes of encapsulation, the header's stamp (sec, nanosec), its frame_id
// (a 4-byte length, then the bytes and their NUL); a ServoStatus's state is the byte after it
if (messages.some((m) => m.data[1] !== 1)) fail("a message not in little-endian CDR");

const image = messages.filter((m) => on(m, "/camera/image_raw"))[frame];
if (!image) fail(`no image ${frame}`);
const twistAt = messages.findIndex((m) => on(m, "/servo/cmd_twist") && stamp(m) === stamp(image));
const status = messages.find((m) => on(m, "/servo/status") && stamp(m) === stamp(image));
if (twistAt < 0 || !status) fail(`no twist and status for image ${frame}`);
const lostStatus = new Uint8Array(status.data);
const idLength = new DataView(lostStatus.buffer).getUint32(12, true);
lostStatus[16 + idLength] = 4;  // ServoStatus.LOST
const zero = new Uint8Array(messages[twistAt].data);
zero.fill(0, zero.length - 48);  // the twist's 6 doubles
const t = messages[twistAt].logTime;
messages.splice(twistAt + 1, 0,
  { ...status, data: lostStatus, logTime: t + 1n, publishTime: t + 1n },
  { ...messages[twistAt], data: zero, logTime: t + 2n, publishTime: t + 2n });
await writeRecords(modulesDir, output, records, messages, "lost_notice.mjs");
console.log(`a LOST status and zero twist after image ${frame}'s answer`);
