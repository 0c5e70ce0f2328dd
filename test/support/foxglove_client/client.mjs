// A Foxglove WebSocket client made of Foxglove's own npm packages, for test/test_view_foxglove.py:
// @foxglove/ws-protocol (the protocol's client), @foxglove/rosmsg (ros2msg schema parser) and
// @foxglove/rosmsg2-serialization (CDR decoder), the pieces the Foxglove app uses for a live
// connection. Nothing in it knows the rig's messages: it decodes whatever the server advertises.
//
// node client.mjs URL SECONDS TOPIC[=COUNT] [TOPIC[=COUNT] ...]
// Prints one JSON line per advertised channel ({"advertise": ...}) and per message received on a
// subscribed topic ({"topic", "schemaName", "logTime", "trailingBytes", "message"}), then
// {"done": true, "complete": bool} once every TOPIC has COUNT messages (default 1), or after
// SECONDS s at most (complete false). Byte arrays are summarized by their length. The server's
// status messages and unadvertisements are printed too ({"status": ...}, {"unadvertise": [...]}).
// A subscription the server refuses as "Unknown channel ID" while the channel is still advertised
// is sent again (a few times, 0.2 s apart): seen once from the foxglove-sdk server for a channel
// advertised a moment before, while other channels of the same server worked.
import wsProtocol from "@foxglove/ws-protocol";
import rosmsg from "@foxglove/rosmsg";
import rosmsg2 from "@foxglove/rosmsg2-serialization";
import WebSocket from "ws";

const { FoxgloveClient } = wsProtocol;
const { parse } = rosmsg;
const { MessageReader } = rosmsg2;

const [url, seconds, ...topics] = process.argv.slice(2);
const wanted = new Map(topics.map((t) => [t.split("=")[0], Number(t.split("=")[1] || 1)]));
const counts = new Map();
// foxglove-sdk servers speak "foxglove.sdk.v1", the same protocol as "foxglove.websocket.v1" under a
// new name (the client library leaves the choice to the WebSocket it is given); offer both.
const client = new FoxgloveClient({
  ws: new WebSocket(url, ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL]),
});
const channels = new Map(); // subscription id -> {channel, reader}
const advertised = new Map(); // channel id -> channel, while advertised
const resubscribed = new Map(); // channel id -> times subscribed again
const RESUBSCRIBE_LIMIT = 10;

function plain(value) {
  if (typeof value === "bigint") return Number(value);
  if (value instanceof Uint8Array || value instanceof Int8Array) return { bytes: value.length };
  if (ArrayBuffer.isView(value)) return Array.from(value, plain);
  if (Array.isArray(value)) return value.map(plain);
  if (value && typeof value === "object") {
    return Object.fromEntries(Object.entries(value).map(([k, v]) => [k, plain(v)]));
  }
  return value;
}

const print = (obj) => process.stdout.write(JSON.stringify(obj) + "\n");

client.on("error", (err) => print({ error: String(err && err.message ? err.message : err) }));
client.on("advertise", (list) => {
  for (const channel of list) {
    print({ advertise: { topic: channel.topic, encoding: channel.encoding, schemaName: channel.schemaName,
      schemaEncoding: channel.schemaEncoding } });
    advertised.set(channel.id, channel);
    if (!wanted.has(channel.topic)) continue;
    let reader = null;
    try {
      reader = new MessageReader(parse(channel.schema, { ros2: true }));
    } catch (err) {
      print({ error: `schema of ${channel.topic}: ${err}` });
    }
    const id = client.subscribe(channel.id);
    channels.set(id, { channel, reader });
  }
});
client.on("unadvertise", (ids) => {
  print({ unadvertise: ids });
  for (const id of ids) advertised.delete(id);
});
client.on("status", (status) => {
  print({ status: { level: status.level, message: status.message } });
  const unknown = /Unknown channel ID: (\d+)/.exec(status.message || "");
  if (!unknown) return;
  const id = Number(unknown[1]);
  const tries = resubscribed.get(id) || 0;
  const entry = [...channels.entries()].find(([, e]) => e.channel.id === id);
  if (!entry || tries >= RESUBSCRIBE_LIMIT) return;
  resubscribed.set(id, tries + 1);
  setTimeout(() => {
    if (!advertised.has(id)) return; // gone: a new advertisement of the topic subscribes anew
    channels.delete(entry[0]);
    channels.set(client.subscribe(id), entry[1]);
  }, 200);
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const entry = channels.get(subscriptionId);
  if (!entry || !entry.reader) return;
  let message;
  try {
    message = entry.reader.readMessage(data);
  } catch (err) {
    print({ topic: entry.channel.topic, error: `decode: ${err}` });
    return;
  }
  print({ topic: entry.channel.topic, schemaName: entry.channel.schemaName, logTime: String(timestamp),
    trailingBytes: entry.reader.lastReadHadTrailingBytes(), message: plain(message) });
  counts.set(entry.channel.topic, (counts.get(entry.channel.topic) || 0) + 1);
  if ([...wanted].every(([topic, count]) => (counts.get(topic) || 0) >= count)) finish(true);
});

function finish(complete) {
  print({ done: true, complete });
  client.close();
  process.exit(0);
}
setTimeout(() => finish(false), Number(seconds) * 1000);
