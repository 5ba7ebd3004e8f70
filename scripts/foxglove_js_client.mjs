// A check of the live view with Foxglove's own JavaScript libraries (the ones the Foxglove app
// uses): @foxglove/ws-protocol's FoxgloveClient, @foxglove/rosmsg's ros2msg parser and
// @foxglove/rosmsg2-serialization's CDR reader and writer.  Not part of the pytest suite (it needs
// npm); tests/e2e/test_foxglove_live_view.py checks the same with Python.
//
//   mkdir -p /tmp/fgjs && (cd /tmp/fgjs && npm install @foxglove/ws-protocol @foxglove/rosmsg \
//       @foxglove/rosmsg2-serialization ws)
//   swarm run SCENARIO --mode realtime --foxglove 8765 &     # with λ at 0
//   NODE_PATH=/tmp/fgjs/node_modules node scripts/foxglove_js_client.mjs ws://127.0.0.1:8765
//
// It subscribes to /swarm/states, /world/markers and /swarm/lambda, decodes them from the
// advertised schemas, publishes λ = 1 (CDR) and exits 0 once the commander's λ is ramping.
import { createRequire } from "module";
const require = createRequire(process.env.NODE_PATH ? process.env.NODE_PATH + "/" : import.meta.url);
const { FoxgloveClient } = require("@foxglove/ws-protocol");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader, MessageWriter } = require("@foxglove/rosmsg2-serialization");
const WebSocket = require("ws");
const url = process.argv[2];
const client = new FoxgloveClient({ ws: new WebSocket(url, ["foxglove.sdk.v1", "foxglove.websocket.v1"]) });
const readers = new Map(); const subs = new Map(); const seen = {}; let lamWriter; let sent = false; const lams = [];
client.on("serverInfo", (i) => console.log("serverInfo caps", i.capabilities, i.supportedEncodings));
client.on("advertise", (chs) => {
  for (const ch of chs) {
    if (!["/swarm/states", "/world/markers", "/swarm/lambda"].includes(ch.topic)) continue;
    const defs = parse(ch.schema, { ros2: true });
    readers.set(ch.id, new MessageReader(defs));
    if (ch.topic === "/swarm/lambda") lamWriter = new MessageWriter(defs);
    const sid = client.subscribe(ch.id); subs.set(sid, ch);
  }
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const ch = subs.get(subscriptionId); const msg = readers.get(ch.id).readMessage(data);
  seen[ch.topic] = (seen[ch.topic] ?? 0) + 1;
  if (seen[ch.topic] === 1) console.log(ch.topic, "t", timestamp.toString(), JSON.stringify(msg).slice(0, 160));
  if (ch.topic === "/swarm/lambda") lams.push(msg.data);
  if (!sent && lamWriter && seen["/swarm/states"] > 20) {
    sent = true;
    const cid = client.advertise({ topic: "/swarm/lambda", encoding: "cdr", schemaName: "std_msgs/msg/Float64" });
    client.sendMessage(cid, lamWriter.writeMessage({ data: 1.0 }));
    console.log("sent λ=1");
  }
  if (lams.some((v) => v > 0.001 && v < 0.999)) { console.log("ramp seen", lams.slice(-3), seen); process.exit(0); }
});
setTimeout(() => { console.log("timeout", seen, lams.slice(-5)); process.exit(1); }, 90000);
