// A Foxglove WebSocket client made of Foxglove's own npm packages, for test/test_view_foxglove.py:
// @foxglove/ws-protocol (the protocol's client), @foxglove/rosmsg (ros2msg schema parser) and
// @foxglove/rosmsg2-serialization (CDR decoder), the pieces the Foxglove app uses for a live
// connection. Nothing in it knows the rig's messages: it decodes whatever the server advertises.
//
// node client.mjs URL SECONDS [--actions JSON] TOPIC[=COUNT] [TOPIC[=COUNT] ...]
// Prints one JSON line for the server's info ({"serverInfo": {capabilities, supportedEncodings}}),
// per advertised channel ({"advertise": ...}) and service ({"service": ...}), and per message
// received on a subscribed topic ({"topic", "schemaName", "logTime", "trailingBytes", "message"}),
// then {"done": true, "complete": bool} once every TOPIC has COUNT messages (default 1) and every
// action is done, or after SECONDS s at most (complete false).
// --actions: a JSON list done one after the other once the server's info has come, each printing
// what came back (what the Foxglove app's service, parameter and publish panels do):
//   {"call": SERVICE, "request": {...}}  -> {"serviceResponse": {service, message}} (decoded with
//                                           the advertised response schema) or {"serviceFailure"};
//                                           "raw": HEX sends those bytes as the request instead
//   {"get": [NAME, ...]} / {"set": [{"name", "value"}, ...]} -> {"parameters": {id, values}};
//                                           "retry": true asks again until every NAME has a value
//   {"publish": {topic, schemaName, encoding: "cdr"|"json", values: [...], periodMs}} advertises a
//     client channel (schema "float64 data") and sends {data: value} per value
//   {"until": {topic, field, value}}       waits for a message on TOPIC (one of the TOPICs) whose
//                                           FIELD equals VALUE -> {"until": {..., sampleIndex}}
//   {"subscribe": [NAME, ...]}            subscribes to parameter updates (printed as {"parameterUpdate"})
//   {"untilParameter": {name, value}}      waits for an update of NAME to VALUE
//   {"untilStatus": TEXT}                 waits for a status message that contains TEXT (one received
//                                           since the previous untilStatus, or the start, counts)
//   {"wait": MS} Byte arrays are summarized by their length. The server's
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
const { MessageReader, MessageWriter } = rosmsg2;

const [url, seconds, ...rest] = process.argv.slice(2);
let actions = [];
if (rest[0] === "--actions") {
  actions = JSON.parse(rest[1]);
  rest.splice(0, 2);
}
const topics = rest;
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

const services = new Map(); // name -> advertised service
const waiting = new Map(); // key -> resolve, for replies the actions wait for
let actionsDone = actions.length === 0;
const untils = []; // {topic, field, value, resolve}

function reply(key) {
  return new Promise((resolve) => waiting.set(key, resolve));
}

function answered(key, value) {
  const resolve = waiting.get(key);
  if (resolve) {
    waiting.delete(key);
    resolve(value);
  }
}

async function advertisedService(name) {
  while (!services.has(name)) await new Promise((r) => setTimeout(r, 100));
  return services.get(name);
}

let callId = 0;
async function callService({ call, request, raw }) {
  const service = await advertisedService(call);
  const writer = new MessageWriter(parse(service.request.schema, { ros2: true }));
  const id = ++callId;
  const data = raw !== undefined ? Uint8Array.from(Buffer.from(raw, "hex")) : writer.writeMessage(request || {});
  client.sendServiceCallRequest({ serviceId: service.id, callId: id, encoding: service.request.encoding, data });
  const answer = await reply(`call ${id}`);
  if (answer.failure !== undefined) {
    print({ serviceFailure: { service: call, message: answer.failure } });
    return;
  }
  const reader = new MessageReader(parse(service.response.schema, { ros2: true }));
  const bytes = new Uint8Array(answer.data.buffer, answer.data.byteOffset, answer.data.byteLength);
  print({ serviceResponse: { service: call, message: plain(reader.readMessage(bytes)) } });
}

let parameterRequest = 0;
async function parameters(action) {
  let id;
  let values;
  for (;;) {
    id = `p${++parameterRequest}`;
    if (action.get) client.getParameters(action.get, id);
    else client.setParameters(action.set, id);
    values = await reply(`parameters ${id}`);
    // "retry": a get sent again (0.5 s apart) until every name asked for has a value
    if (!action.retry || action.get.every((name) => values.some((p) => p.name === name))) break;
    await new Promise((r) => setTimeout(r, 500));
  }
  print({ parameters: { id, values: values.map((p) => ({ name: p.name, value: p.value, type: p.type })) } });
}

async function publish({ topic, schemaName, encoding, values, periodMs }) {
  const definition = "float64 data";
  const channel = client.advertise({ topic, encoding, schemaName, schemaEncoding: "ros2msg", schema: definition });
  const writer = new MessageWriter(parse(definition, { ros2: true }));
  for (const value of values) {
    const message = { data: value === "NaN" ? NaN : value };
    const data = encoding === "json" ? new TextEncoder().encode(JSON.stringify(message)) : writer.writeMessage(message);
    client.sendMessage(channel, data);
    await new Promise((r) => setTimeout(r, periodMs || 5));
  }
  print({ published: { topic, count: values.length } });
}

async function until({ topic, field, value }) {
  const message = await new Promise((resolve) => untils.push({ topic, field, value, resolve }));
  print({ until: { topic, field, value, sampleIndex: plain(message.sample_index) } });
}

async function runActions() {
  for (const action of actions) {
    if (action.call) await callService(action);
    else if (action.get || action.set) await parameters(action);
    else if (action.publish) await publish(action.publish);
    else if (action.until) await until(action.until);
    else if (action.subscribe) client.subscribeParameterUpdates(action.subscribe);
    else if (action.untilStatus) await untilStatus(action.untilStatus);
    else if (action.untilParameter) {
      await new Promise((resolve) => parameterUntils.push({ ...action.untilParameter, resolve }));
      print({ untilParameter: action.untilParameter });
    }
    else if (action.wait) await new Promise((r) => setTimeout(r, action.wait));
  }
  actionsDone = true;
  finishIfComplete();
}

function finishIfComplete() {
  if (actionsDone && [...wanted].every(([topic, count]) => (counts.get(topic) || 0) >= count)) finish(true);
}

client.on("serverInfo", (info) => {
  print({ serverInfo: { capabilities: info.capabilities, supportedEncodings: info.supportedEncodings || [] } });
  if (!actionsDone) {
    runActions().catch((err) => {
      print({ error: `actions: ${err}` });
      finish(false);
    });
  }
});
client.on("advertiseServices", (list) => {
  for (const service of list) {
    services.set(service.name, service);
    print({ service: { name: service.name, type: service.type, request: service.request && service.request.schemaName,
      response: service.response && service.response.schemaName, encoding: service.request && service.request.encoding } });
  }
});
client.on("serviceCallResponse", (r) => answered(`call ${r.callId}`, { data: r.data }));
client.on("serviceCallFailure", (r) => answered(`call ${r.callId}`, { failure: r.message }));
const parameterUntils = []; // {name, value, resolve}
client.on("parameterValues", (event) => {
  if (event.id !== undefined && waiting.has(`parameters ${event.id}`)) {
    answered(`parameters ${event.id}`, event.parameters);
    return;
  }
  print({ parameterUpdate: event.parameters.map((p) => ({ name: p.name, value: p.value })) });
  for (let i = parameterUntils.length - 1; i >= 0; i--) {
    const u = parameterUntils[i];
    if (event.parameters.some((p) => p.name === u.name && p.value === u.value)) {
      parameterUntils.splice(i, 1);
      u.resolve();
    }
  }
});

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
const statusUntils = []; // {text, resolve}
let unmatchedStatuses = []; // messages since the last untilStatus: one may arrive during an earlier action
function untilStatus(text) {
  const seen = unmatchedStatuses.some((message) => message.includes(text));
  unmatchedStatuses = [];
  if (seen) return Promise.resolve();
  return new Promise((resolve) => statusUntils.push({ text, resolve }));
}
client.on("status", (status) => {
  print({ status: { level: status.level, message: status.message } });
  unmatchedStatuses.push(status.message || "");
  for (let i = statusUntils.length - 1; i >= 0; i--) {
    if ((status.message || "").includes(statusUntils[i].text)) {
      statusUntils.splice(i, 1)[0].resolve();
      unmatchedStatuses = []; // taken by that wait
    }
  }
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
  for (let i = untils.length - 1; i >= 0; i--) {
    const u = untils[i];
    if (u.topic === entry.channel.topic && plain(message[u.field]) === u.value) {
      untils.splice(i, 1);
      u.resolve(message);
    }
  }
  finishIfComplete();
});

function finish(complete) {
  print({ done: true, complete });
  client.close();
  process.exit(0);
}
setTimeout(() => finish(false), Number(seconds) * 1000);
