// Rewrites a recorded run in an order rosbag2 may record the live cell in: messages as they
// arrive, each frame's image ahead of that frame's simulator status and camera pose (cellsim
// publishes the status first, but three topics on two transports arrive in any order). Each
// status and pose is moved to just after the image that carries its stamp.
// `servo replay --expect-identical` must reproduce the twists of that recording too.
//
//   node arrival_order.mjs MODULES_DIR IN.mcap OUT.mcap   (prints how many it moved)
import { readRecords, scriptArgs, stampKey as stamp, topicTest, writeRecords } from "./mcap_records.mjs";

const { args } = scriptArgs("arrival_order", "MODULES_DIR IN.mcap OUT.mcap", (a) => a.length === 3);
const [modulesDir, input, output] = args;
const records = readRecords(modulesDir, input);
const { messages } = records;
const is = topicTest(records);

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

await writeRecords(modulesDir, output, records, out, "arrival_order.mjs");
console.log(`arrival_order: ${count} statuses and poses moved after their images`);
