// Rewrites a recorded bin/demo run as a recording that stopped mid-run (a full disk, the size
// limit) in the order the recorder can meet it: the servo's twist for a frame is queued as it
// arrives, the frame's image a moment later, and the stop falls between them. The file keeps
// every message before the FRAME-th image, that image's twist, and (unless --no-metadata) the
// recorder's "recording_stopped" metadata record. `servo replay --expect-identical` must count
// that twist apart (it answers an image past the cut) when the file says it stopped, and as
// unanswered when it does not.
//
//   node stopped_before_its_image.mjs MODULES_DIR IN.mcap OUT.mcap FRAME [--no-metadata]
import { readRecords, scriptArgs, stampKey as stamp, topicTest, writeRecords } from "./mcap_records.mjs";

const { args, fail } = scriptArgs("stopped_before_its_image", "MODULES_DIR IN.mcap OUT.mcap FRAME [--no-metadata]",
  (a) => (a.length === 4 || (a.length === 5 && a[4] === "--no-metadata")) && Number(a[3]) >= 2);
const [modulesDir, input, output, , flag] = args;
const frame = Number(args[3]);
const records = readRecords(modulesDir, input);
const { messages } = records;
const on = topicTest(records);
const isTwist = (m) => on(m, "/servo/cmd_twist");
const isImage = (m) => on(m, "/camera/image_raw");

const images = messages.filter(isImage);
if (images.length <= frame) fail(`${images.length} images, not more than ${frame}`);
const cut = images[frame];
const at = messages.indexOf(cut);
const answer = messages.findIndex((m, i) => i > at && isTwist(m) && stamp(m) === stamp(cut));
if (answer < 0) fail(`no twist answers image ${frame}`);
const kept = messages.slice(0, at);
kept.push({ ...messages[answer], logTime: cut.logTime, publishTime: cut.publishTime });
const metadata = flag ? [] : [{ name: "recording_stopped", metadata: new Map([["reason", "stopped at the size limit (a test)"]]) }];
await writeRecords(modulesDir, output, records, kept, "stopped_before_its_image.mjs", metadata);
console.log(`stopped at image ${frame} of ${images.length}, its twist kept (${kept.length} messages)${flag ? ", no metadata" : ""}`);
