#!/usr/bin/env node
// Check a deckpose MCAP log (and optionally its Foxglove layout) the way the Foxglove /
// Lichtblick app reads them: the same reader libraries (@mcap/core with a zstd handler,
// protobufjs built from each schema's FileDescriptorSet), the same channel rules (json +
// jsonschema, protobuf + protobuf) and the panel config keys the app's Image, 3D and Plot
// panels read. It proves the files parse and hang together; it does not run the app's GUI.
//
// Usage: node check.mjs RUN/log.mcap [RUN/foxglove_layout.json]
// Prints a per-topic summary, then every problem; exits 1 on any problem, 2 on bad usage.

import { open, readFile } from "node:fs/promises";
import { createRequire } from "node:module";

import { McapIndexedReader, McapStreamReader } from "@mcap/core";

const require = createRequire(import.meta.url);
const protobuf = require("protobufjs");
const { FileDescriptorSet } = require("protobufjs/ext/descriptor");
const zstd = require("@foxglove/wasm-zstd");
const officialSchemas = require("@foxglove/schemas/jsonschema.js");

// Findings, grouped: the same kind of finding on the same topic is printed once with a count.
const problems = new Map();
const warnings = new Map();
function record(store, where, what, kind) {
  const key = kind == undefined ? `${where}: ${what}` : `${where.split(" @ ")[0]}: ${kind}`;
  const entry = store.get(key) ?? { text: `${where}: ${what}`, count: 0 };
  entry.count += 1;
  store.set(key, entry);
}
const problem = (where, what, kind) => record(problems, where, what, kind);
const warn = (where, what, kind) => record(warnings, where, what, kind);

// Schemas the app's panels render (ImageMode, ImageAnnotations, FrameAxes), by role.
const IMAGE_SCHEMAS = new Set(["foxglove.CompressedImage", "foxglove.RawImage"]);
const CALIBRATION_SCHEMAS = new Set(["foxglove.CameraCalibration"]);
const ANNOTATION_SCHEMAS = new Set(["foxglove.ImageAnnotations"]);
const TRANSFORM_SCHEMAS = new Set(["foxglove.FrameTransforms", "foxglove.FrameTransform"]);
// CompressedImage.format values the schema documents (decoded as a Blob of type image/<format>).
const IMAGE_FORMATS = new Set(["jpeg", "png", "webp", "avif"]);
// PinholeCameraModel accepts "" (none), plumb_bob and rational_polynomial; D lengths per the schema.
const DISTORTION_D_LENGTH = new Map([["", 0], ["plumb_bob", 5], ["rational_polynomial", 8]]);

function ns(stamp) {
  // A decoded google.protobuf.Timestamp after the app's rename (seconds->sec, nanos->nsec).
  return BigInt(stamp.sec) * 1_000_000_000n + BigInt(stamp.nsec);
}
// Seconds, exact to the nanosecond (trailing zeros dropped).
function sec(t) {
  const n = BigInt(t);
  const sign = n < 0n ? "-" : "";
  const a = n < 0n ? -n : n;
  const frac = String(a % 1_000_000_000n).padStart(9, "0").replace(/0+$/, "");
  return `${sign}${a / 1_000_000_000n}${frac ? `.${frac}` : ""}`;
}

// ---------------------------------------------------------------------------------------------
// Channel parsing, following the app's rules (mcap-support parseChannel).

function parseJsonSchemaLikeApp(schema, typeName, datatypes = new Map()) {
  // Same acceptance rules as the app's parseJsonSchema: an object with `properties`, each a
  // boolean / string / number / integer / object / array (or an enum given as numeric oneOf).
  if (schema.type !== "object") {
    throw new Error(`expected "type": "object" for ${typeName}, got ${JSON.stringify(schema.type)}`);
  }
  if (schema.properties == undefined || typeof schema.properties !== "object") {
    throw new Error(
      `${typeName} has no "properties" (the app runs Object.entries(schema.properties) and fails)`,
    );
  }
  const fields = new Map();
  for (const [name, field] of Object.entries(schema.properties)) {
    if (Array.isArray(field.oneOf)) {
      if (!field.oneOf.every((alt) => typeof alt.const === "number")) {
        throw new Error(`${typeName}.${name}: oneOf alternatives must have number values`);
      }
      fields.set(name, "enum");
      continue;
    }
    switch (field.type) {
      case "boolean":
      case "string":
      case "number":
      case "integer":
        fields.set(name, field.type);
        break;
      case "object":
        parseJsonSchemaLikeApp(field, `${typeName}.${name}`, datatypes);
        fields.set(name, "object");
        break;
      case "array":
        if (!["boolean", "string", "number", "integer", "object"].includes(field.items?.type)) {
          throw new Error(`${typeName}.${name}: unsupported array item type ${JSON.stringify(field.items?.type)}`);
        }
        fields.set(name, "array");
        break;
      default:
        throw new Error(`${typeName}.${name}: unsupported type ${JSON.stringify(field.type)}`);
    }
  }
  datatypes.set(typeName, fields);
  return datatypes;
}

function renameTimeFields(root, fullName) {
  // The app renames Timestamp/Duration fields to sec/nsec before decoding.
  const type = root.lookup(fullName);
  if (!(type instanceof protobuf.Type)) {
    return;
  }
  const names = type.fieldsArray.map((f) => f.name).sort().join(",");
  if (names !== "nanos,seconds") {
    throw new Error(`${fullName} has fields ${names}, expected nanos,seconds`);
  }
  for (const field of type.fieldsArray) {
    field.name = field.name === "seconds" ? "sec" : "nsec";
  }
  type.setup();
}

function parseChannel(channel, schema) {
  if (channel.messageEncoding === "json") {
    if (schema != undefined && schema.encoding !== "jsonschema") {
      throw new Error(`json messages with schema encoding '${schema.encoding}' (the app expects jsonschema)`);
    }
    let datatypes = new Map();
    if (schema != undefined && schema.data.length > 0) {
      const parsed = JSON.parse(new TextDecoder().decode(schema.data));
      if (typeof parsed !== "object" || parsed == undefined) {
        throw new Error("jsonschema is not a JSON object");
      }
      datatypes = parseJsonSchemaLikeApp(parsed, schema.name);
    }
    const decoder = new TextDecoder();
    return { kind: "json", datatypes, deserialize: (data) => JSON.parse(decoder.decode(data)) };
  }
  if (channel.messageEncoding === "protobuf") {
    if (schema?.encoding !== "protobuf") {
      throw new Error(`protobuf messages with schema encoding '${schema?.encoding}' (the app expects protobuf)`);
    }
    const root = protobuf.Root.fromDescriptor(FileDescriptorSet.decode(schema.data));
    root.resolveAll();
    const type = root.lookupType(schema.name);
    if (type.fullName.replace(/^\./, "") !== schema.name) {
      throw new Error(`schema name ${schema.name} is not the fully qualified type ${type.fullName}`);
    }
    renameTimeFields(root, ".google.protobuf.Timestamp");
    renameTimeFields(root, ".google.protobuf.Duration");
    const deserialize = (data) =>
      type.toObject(type.decode(data), { defaults: true, longs: Number, enums: Number });
    return { kind: "protobuf", type, deserialize };
  }
  throw new Error(`message encoding ${channel.messageEncoding} is not one deckpose writes (json, protobuf)`);
}

function protoFieldsAgainstOfficial(type, official, where, seen = new Set()) {
  // Every field our descriptor has must exist in Foxglove's published schema (same names).
  if (seen.has(type.fullName)) {
    return;
  }
  seen.add(type.fullName);
  const props = official?.properties ?? {};
  for (const field of type.fieldsArray) {
    const name = field.name === "sec" || field.name === "nsec" ? undefined : field.name;
    if (name == undefined) {
      continue;
    }
    if (!(name in props)) {
      problem(where, `field ${type.name}.${name} is not in Foxglove's ${official?.title ?? "schema"}`);
      continue;
    }
    const sub = props[name].type === "array" ? props[name].items : props[name];
    if (field.resolvedType instanceof protobuf.Type && sub?.properties != undefined) {
      protoFieldsAgainstOfficial(field.resolvedType, sub, where, seen);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Reading the file twice: as a stream (every record, in file order) and indexed (summary).

async function decompressHandlers() {
  await zstd.isLoaded;
  return { zstd: (buffer, size) => new Uint8Array(zstd.decompress(buffer, Number(size))) };
}

function streamRead(bytes, handlers) {
  const reader = new McapStreamReader({ decompressHandlers: handlers, validateCrcs: true, includeChunks: true });
  reader.append(bytes);
  const out = { schemas: new Map(), channels: new Map(), messages: [], chunks: [], statistics: undefined, profile: undefined };
  for (let rec; (rec = reader.nextRecord()); ) {
    switch (rec.type) {
      case "Header":
        out.profile = rec.profile;
        break;
      case "Schema":
        out.schemas.set(rec.id, rec);
        break;
      case "Channel":
        out.channels.set(rec.id, rec);
        break;
      case "Message":
        out.messages.push(rec);
        break;
      case "Chunk":
        out.chunks.push(rec);
        break;
      case "Statistics":
        out.statistics = rec;
        break;
    }
  }
  if (!reader.done()) {
    problem("file", "the stream reader did not reach a valid footer (truncated or malformed file)");
  }
  return out;
}

async function indexedRead(path, handlers) {
  const fh = await open(path, "r");
  try {
    const size = BigInt((await fh.stat()).size);
    const readable = {
      size: async () => size,
      read: async (offset, length) => {
        const buf = new Uint8Array(Number(length));
        await fh.read(buf, 0, buf.length, Number(offset));
        return buf;
      },
    };
    const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers: handlers });
    const counts = new Map();
    let last = -1n;
    let ordered = true;
    for await (const msg of reader.readMessages({ validateCrcs: true })) {
      counts.set(msg.channelId, (counts.get(msg.channelId) ?? 0) + 1);
      ordered &&= msg.logTime >= last;
      last = msg.logTime;
    }
    return { reader, counts, ordered };
  } finally {
    await fh.close();
  }
}

// ---------------------------------------------------------------------------------------------
// Message content checks.

function imageSize(data, format) {
  const b = data;
  const magic = {
    png: b[0] === 0x89 && b[1] === 0x50 && b[2] === 0x4e && b[3] === 0x47,
    jpeg: b[0] === 0xff && b[1] === 0xd8 && b[2] === 0xff,
    webp: String.fromCharCode(...b.subarray(0, 4)) === "RIFF" && String.fromCharCode(...b.subarray(8, 12)) === "WEBP",
    avif: String.fromCharCode(...b.subarray(4, 12)) === "ftypavif",
  };
  if (!magic[format]) {
    return { error: `data does not start with a ${format} signature` };
  }
  if (format === "png") {
    const view = new DataView(b.buffer, b.byteOffset, b.byteLength);
    return { width: view.getUint32(16), height: view.getUint32(20) };
  }
  return {};
}

function checkCalibration(cal, where) {
  const model = cal.distortion_model;
  if (!DISTORTION_D_LENGTH.has(model)) {
    problem(where, `distortion_model "${model}" is not one the app's PinholeCameraModel accepts`, "distortion model");
  } else if (model !== "" && cal.D.length !== DISTORTION_D_LENGTH.get(model)) {
    problem(where, `D has ${cal.D.length} values, ${model} needs ${DISTORTION_D_LENGTH.get(model)}`, "D length");
  }
  if (!(cal.width > 0 && cal.height > 0)) {
    problem(where, `image size ${cal.width}x${cal.height}`, "calibration size");
  }
  if (cal.K.length !== 9 || cal.P.length !== 12 || (cal.R.length !== 0 && cal.R.length !== 9)) {
    problem(where, `K/P/R lengths ${cal.K.length}/${cal.P.length}/${cal.R.length}, need 9/12/9`, "K/P/R lengths");
  } else if (!(cal.P[0] > 0 && cal.P[5] > 0)) {
    problem(where, `focal lengths in P are ${cal.P[0]}, ${cal.P[5]}`, "focal length");
  }
}

function checkTransforms(msg, where) {
  const parentOf = new Map();
  for (const tf of msg.transforms) {
    const q = tf.rotation;
    const norm = Math.hypot(q.x, q.y, q.z, q.w);
    const t = tf.translation;
    if (!tf.parent_frame_id || !tf.child_frame_id || tf.parent_frame_id === tf.child_frame_id) {
      problem(where, `transform ${tf.parent_frame_id} -> ${tf.child_frame_id} has a bad frame id`, "frame id");
    }
    if (Math.abs(norm - 1) > 1e-6 || ![t.x, t.y, t.z].every(Number.isFinite)) {
      problem(where, `transform to ${tf.child_frame_id}: |q| = ${norm}, t = ${t.x},${t.y},${t.z}`, "bad transform");
    }
    if (parentOf.has(tf.child_frame_id)) {
      problem(where, `frame ${tf.child_frame_id} has two parents in one message`, "two parents");
    }
    parentOf.set(tf.child_frame_id, tf.parent_frame_id);
  }
  for (const child of parentOf.keys()) {
    const seen = new Set([child]);
    for (let f = parentOf.get(child); f != undefined; f = parentOf.get(f)) {
      if (seen.has(f)) {
        problem(where, `transform cycle through ${f}`, "cycle");
        break;
      }
      seen.add(f);
    }
  }
  return parentOf;
}

function checkAnnotations(msg, frame, where) {
  const { stampNs, width, height } = frame;
  let points = 0;
  for (const kind of ["points", "texts", "circles"]) {
    for (const a of msg[kind] ?? []) {
      if (stampNs != undefined && ns(a.timestamp) !== stampNs) {
        problem(where, `${kind} timestamp ${sec(ns(a.timestamp))} s differs from the image's ${sec(stampNs)} s`, "annotation timestamp");
      }
    }
  }
  for (const p of msg.points ?? []) {
    if (!(p.type >= 0 && p.type <= 4)) {
      problem(where, `points annotation type ${p.type} is unknown`, "annotation type");
    }
    for (const xy of p.points) {
      points += 1;
      // Image pixel coordinates with the origin at the top-left corner of the top-left pixel.
      if (width != undefined && !(xy.x >= 0 && xy.x <= width && xy.y >= 0 && xy.y <= height)) {
        problem(where, `point (${xy.x.toFixed(2)}, ${xy.y.toFixed(2)}) lies outside the ${width}x${height} image`, "point outside image");
      }
    }
  }
  return points;
}

// ---------------------------------------------------------------------------------------------
// The log.

async function checkLog(path) {
  const handlers = await decompressHandlers();
  const bytes = new Uint8Array(await readFile(path));
  const stream = streamRead(bytes, handlers);
  const topics = new Map(); // topic -> summary
  const channels = new Map(); // channel id -> { channel, schema, parsed }
  const frames = new Map(); // log time -> joined content of that instant

  for (const chunk of stream.chunks) {
    if (chunk.compression !== "zstd") {
      problem("file", `a chunk uses compression "${chunk.compression}", expected zstd`);
    }
  }
  for (const [id, channel] of stream.channels) {
    const schema = channel.schemaId === 0 ? undefined : stream.schemas.get(channel.schemaId);
    const entry = { channel, schema, parsed: undefined };
    try {
      entry.parsed = parseChannel(channel, schema);
      if (entry.parsed.kind === "protobuf") {
        const official = officialSchemas[schema.name.replace(/^foxglove\./, "")];
        if (schema.name.startsWith("foxglove.") && official == undefined) {
          problem(channel.topic, `${schema.name} is not a published Foxglove schema`);
        } else if (official != undefined) {
          protoFieldsAgainstOfficial(entry.parsed.type, official, channel.topic);
        }
      }
    } catch (err) {
      problem(channel.topic, `the app cannot parse this channel: ${err.message}`);
    }
    channels.set(id, entry);
    topics.set(channel.topic, {
      schema: schema?.name ?? "(none)", encoding: channel.messageEncoding, count: 0,
      first: undefined, last: undefined, datatypes: entry.parsed?.datatypes, info: "",
    });
  }

  let pointsTotal = 0;
  let emptyAnnotations = 0;
  for (const msg of stream.messages) {
    const entry = channels.get(msg.channelId);
    const topic = entry?.channel.topic ?? `(channel ${msg.channelId})`;
    const t = topics.get(topic);
    if (entry == undefined || t == undefined) {
      problem(topic, "message on a channel that was never defined");
      continue;
    }
    if (t.last != undefined && msg.logTime < t.last) {
      problem(topic, `log time goes back from ${sec(t.last)} s to ${sec(msg.logTime)} s`, "time goes back");
    } else if (t.last != undefined && msg.logTime === t.last) {
      problem(topic, `two messages at log time ${sec(msg.logTime)} s (the app shows only the last)`, "repeated time");
    }
    if (msg.publishTime !== msg.logTime) {
      warn(topic, `publish time differs from log time at ${sec(msg.logTime)} s`, "publish time");
    }
    t.first ??= msg.logTime;
    t.last = msg.logTime;
    t.count += 1;
    if (entry.parsed == undefined) {
      continue;
    }
    let decoded;
    try {
      decoded = entry.parsed.deserialize(msg.data);
    } catch (err) {
      problem(topic, `message at ${sec(msg.logTime)} s does not decode: ${err.message}`);
      continue;
    }
    const frame = frames.get(msg.logTime) ?? { annotations: [] };
    frames.set(msg.logTime, frame);
    const schemaName = entry.schema?.name ?? "";
    const where = `${topic} @ ${sec(msg.logTime)} s`;
    if (entry.parsed.kind === "json") {
      const fields = t.datatypes?.get(schemaName);
      if (typeof decoded !== "object" || decoded == undefined || Array.isArray(decoded)) {
        problem(where, "JSON message is not an object", "not an object");
      } else if (fields != undefined) {
        for (const [key, value] of Object.entries(decoded)) {
          const type = fields.get(key);
          if (type == undefined) {
            warn(topic, `field ${key} is not in the channel's jsonschema (Plot cannot suggest it)`, "field not in schema");
          } else if ((type === "number" || type === "integer") && value !== null && typeof value !== "number") {
            problem(where, `field ${key} should be a number or null, got ${JSON.stringify(value)}`, "non-numeric value");
          }
        }
      }
    } else if ("timestamp" in decoded && decoded.timestamp != undefined && ns(decoded.timestamp) !== msg.logTime) {
      problem(where, `header timestamp ${sec(ns(decoded.timestamp))} s differs from the log time`, "header timestamp");
    }
    if (IMAGE_SCHEMAS.has(schemaName)) {
      frame.image = { topic, frameId: decoded.frame_id, stampNs: ns(decoded.timestamp) };
      if (schemaName === "foxglove.CompressedImage") {
        if (!IMAGE_FORMATS.has(decoded.format)) {
          problem(where, `format "${decoded.format}" is not one of ${[...IMAGE_FORMATS].join(", ")}`, "image format");
        } else {
          const size = imageSize(decoded.data, decoded.format);
          if (size.error) {
            problem(where, size.error, "image signature");
          }
          Object.assign(frame.image, { width: size.width, height: size.height });
        }
      }
    } else if (CALIBRATION_SCHEMAS.has(schemaName)) {
      checkCalibration(decoded, where);
      frame.calibration = { frameId: decoded.frame_id, width: decoded.width, height: decoded.height };
    } else if (TRANSFORM_SCHEMAS.has(schemaName)) {
      const list = schemaName === "foxglove.FrameTransform" ? { transforms: [decoded] } : decoded;
      frame.parentOf = new Map([...(frame.parentOf ?? []), ...checkTransforms(list, where)]);
    } else if (ANNOTATION_SCHEMAS.has(schemaName)) {
      frame.annotations.push({ topic, msg: decoded, where });
    } else if (schemaName === "foxglove.SceneUpdate") {
      frame.scenes = [...(frame.scenes ?? []), { msg: decoded, where }];
    }
  }

  // Join what was logged at the same instant (one image per instant in deckpose logs).
  const allFrames = new Set();
  for (const [, frame] of frames) {
    for (const f of frame.parentOf?.keys() ?? []) {
      allFrames.add(f);
    }
    for (const f of frame.parentOf?.values() ?? []) {
      allFrames.add(f);
    }
    const image = frame.image;
    const cal = frame.calibration;
    const where = image ? `${image.topic} @ ${sec(image.stampNs)} s` : "annotations";
    if (image && cal) {
      if (image.frameId !== cal.frameId) {
        problem(where, `image frame_id "${image.frameId}" differs from the calibration's "${cal.frameId}"`, "frame id mismatch");
      }
      if (image.width != undefined && (image.width !== cal.width || image.height !== cal.height)) {
        problem(where, `image is ${image.width}x${image.height}, calibration says ${cal.width}x${cal.height}`, "size mismatch");
      }
    }
    for (const sc of frame.scenes ?? []) {
      // The 3D panel places an entity with its frame's transform: a frame /tf does not have at
      // this instant draws nothing (and shows an error in the panel's settings).
      for (const e of sc.msg.entities ?? []) {
        if (frame.parentOf && !frame.parentOf.has(e.frame_id)) {
          problem(sc.where, `scene entity "${e.id}" is in frame "${e.frame_id}", which has no transform at this time`, "scene frame");
        }
      }
    }
    if (image && frame.parentOf && !frame.parentOf.has(image.frameId)) {
      problem(where, `no transform to the image frame "${image.frameId}" at this time`, "no camera transform");
    }
    for (const a of frame.annotations) {
      const n = checkAnnotations(a.msg, {
        stampNs: image?.stampNs, width: image?.width ?? cal?.width, height: image?.height ?? cal?.height,
      }, a.where);
      pointsTotal += n;
      if (n === 0) {
        emptyAnnotations += 1;
      }
      if (!image) {
        problem(a.where, "annotations logged at an instant with no image", "annotation without image");
      }
    }
  }
  if (emptyAnnotations > 0) {
    warn("annotations", `${emptyAnnotations} annotation messages carry no points (frames with nothing detected)`);
  }

  // The summary: statistics, and an indexed read that must agree with the stream read.
  const counted = new Map([...channels.keys()].map((id) => [id, 0]));
  for (const msg of stream.messages) {
    counted.set(msg.channelId, (counted.get(msg.channelId) ?? 0) + 1);
  }
  let indexed;
  try {
    indexed = await indexedRead(path, handlers);
  } catch (err) {
    problem("summary", `the indexed reader (used for local files) fails: ${err.message}`);
  }
  if (indexed) {
    const stats = indexed.reader.statistics;
    if (stats == undefined) {
      problem("summary", "no Statistics record");
    } else {
      if (stats.messageCount !== BigInt(stream.messages.length)) {
        problem("summary", `Statistics says ${stats.messageCount} messages, the file has ${stream.messages.length}`);
      }
      if (stats.chunkCount !== stream.chunks.length) {
        problem("summary", `Statistics says ${stats.chunkCount} chunks, the file has ${stream.chunks.length}`);
      }
      for (const [id, n] of counted) {
        if (stats.channelMessageCounts.get(id) !== BigInt(n)) {
          problem("summary", `channel ${id}: Statistics count ${stats.channelMessageCounts.get(id)}, file has ${n}`);
        }
      }
      const times = stream.messages.map((m) => m.logTime);
      if (times.length && (stats.messageStartTime !== times.reduce((a, b) => (b < a ? b : a)) ||
                           stats.messageEndTime !== times.reduce((a, b) => (b > a ? b : a)))) {
        problem("summary", "Statistics start/end times do not match the messages");
      }
    }
    if (indexed.reader.chunkIndexes.length !== stream.chunks.length) {
      problem("summary", `${indexed.reader.chunkIndexes.length} chunk indexes for ${stream.chunks.length} chunks`);
    }
    if (indexed.reader.channelsById.size !== stream.channels.size || indexed.reader.schemasById.size !== stream.schemas.size) {
      problem("summary", "the summary does not repeat every schema and channel");
    }
    for (const [id, n] of counted) {
      if ((indexed.counts.get(id) ?? 0) !== n) {
        problem("summary", `channel ${id}: the indexed reader returns ${indexed.counts.get(id) ?? 0} messages, the file has ${n}`);
      }
    }
    if (!indexed.ordered) {
      problem("summary", "the indexed reader does not return messages in log-time order");
    }
  }
  return { topics, frames: allFrames, stream, pointsTotal, indexed: indexed != undefined };
}

// ---------------------------------------------------------------------------------------------
// The layout.

const PANEL_TYPES = new Set(["Image", "ImageViewPanel", "3D", "Plot", "RawMessages", "Tab", "StateTransitions", "Table", "Indicator", "Gauge", "Map", "Log"]);
const SCENE_TRANSFORM_KEYS = new Set(["editable", "showLabel", "labelSize", "axisScale", "lineWidth", "lineColor", "enablePreloading"]);
const TIMESTAMP_METHODS = new Set(["receiveTime", "headerStamp"]);
const X_AXIS_VALS = new Set(["timestamp", "index", "custom", "currentCustom"]);

function mosaicLeaves(node, where, out = []) {
  if (typeof node === "string") {
    out.push(node);
  } else if (node && typeof node === "object") {
    if (node.direction !== "row" && node.direction !== "column") {
      problem(where, `split direction ${JSON.stringify(node.direction)} (row or column)`);
    }
    if (node.splitPercentage != undefined && !(node.splitPercentage > 0 && node.splitPercentage < 100)) {
      problem(where, `splitPercentage ${node.splitPercentage}`);
    }
    mosaicLeaves(node.first, where, out);
    mosaicLeaves(node.second, where, out);
  } else {
    problem(where, `layout node ${JSON.stringify(node)} is neither a panel id nor a split`);
  }
  return out;
}

function parseMessagePath(path) {
  // The topic part and field names, per the app's message-path grammar: a topic is
  // /id/id... with id = [a-zA-Z0-9_-]+, or a double-quoted string; then .name parts.
  let rest = path;
  let topic;
  if (rest.startsWith('"')) {
    const m = /^"((?:[^"\\]|\\\\|\\")*)"/.exec(rest);
    if (!m) {
      return undefined;
    }
    topic = m[1].replace(/\\(["\\])/g, "$1");
    rest = rest.slice(m[0].length);
  } else {
    const m = /^(?:\/[A-Za-z0-9_-]*)+/.exec(rest);
    if (!m) {
      return undefined;
    }
    topic = m[0];
    rest = rest.slice(m[0].length);
  }
  const names = [];
  while (rest.length > 0) {
    const m = /^\.([A-Za-z0-9_-]+)/.exec(rest);
    if (!m) {
      return undefined;
    }
    names.push(m[1]);
    rest = rest.slice(m[0].length);
  }
  return { topic, names };
}

function migrateLegacyImageConfig(legacy, panel) {
  // Studio 1.48's ImageViewPanel reads cameraTopic (string) and enabledMarkerTopics (string[]);
  // the newer app's layout migration (migrateLegacyToNewImagePanels) turns them into an Image
  // panel's imageMode.imageTopic and imageMode.annotations {topic: {visible: true}}.
  if (typeof legacy.cameraTopic !== "string" || legacy.cameraTopic === "") {
    problem(panel, "cameraTopic (the legacy image panel's image topic) must be a non-empty string");
  }
  const markers = legacy.enabledMarkerTopics ?? [];
  if (!Array.isArray(markers) || !markers.every((t) => typeof t === "string")) {
    problem(panel, "enabledMarkerTopics must be an array of topic names");
  }
  if (legacy.imageMode != undefined) {
    warn(panel, "imageMode in a legacy ImageViewPanel config is dropped by the newer app's migration");
  }
  return {
    imageMode: {
      imageTopic: typeof legacy.cameraTopic === "string" && legacy.cameraTopic !== "" ? legacy.cameraTopic : undefined,
      annotations: Object.fromEntries((Array.isArray(markers) ? markers : []).map((t) => [t, { visible: true }])),
    },
  };
}

function checkLayout(layout, log, referenced) {
  const where = "layout";
  if (typeof layout !== "object" || layout == undefined || Array.isArray(layout)) {
    problem(where, "not a JSON object");
    return;
  }
  for (const key of ["configById", "globalVariables", "userNodes"]) {
    if (typeof layout[key] !== "object" || layout[key] == undefined || Array.isArray(layout[key])) {
      problem(where, `"${key}" must be an object`);
    }
  }
  if (typeof layout.playbackConfig?.speed !== "number") {
    problem(where, `"playbackConfig": {"speed": number} is missing (the app reads playbackConfig.speed)`);
  }
  const leaves = mosaicLeaves(layout.layout, where);
  const configs = layout.configById ?? {};
  for (const id of leaves) {
    if (!(id in configs)) {
      problem(where, `panel ${id} is in the layout but has no config`);
    }
  }
  for (const id of Object.keys(configs)) {
    if (!leaves.includes(id)) {
      warn(where, `config for ${id} is not placed in the layout (the app drops it)`);
    }
  }
  const topicSchema = (topic) => log.topics.get(topic)?.schema;
  const needTopic = (panel, topic, schemas, role) => {
    referenced.add(topic);
    const schema = topicSchema(topic);
    if (schema == undefined) {
      problem(panel, `${role} topic ${topic} is not in the log`);
    } else if (schemas && !schemas.has(schema)) {
      problem(panel, `${role} topic ${topic} has schema ${schema}, not one of ${[...schemas].join(", ")}`);
    }
  };
  for (const [id, original] of Object.entries(configs)) {
    let type = id.split("!")[0];
    let config = original;
    const panel = `layout ${id}`;
    if (!id.includes("!") || !PANEL_TYPES.has(type)) {
      problem(panel, `panel id must be "<Type>!<id>" with a known panel type, got "${id}"`);
      continue;
    }
    if (type === "ImageViewPanel") {
      // Foxglove Studio 1.48's image panel; the newer app (and Lichtblick) migrate it on import.
      config = migrateLegacyImageConfig(original, panel);
      type = "Image";
    }
    if (type === "Image" || type === "3D") {
      const image = config.imageMode ?? {};
      if (type === "Image") {
        if (image.imageTopic == undefined) {
          problem(panel, "imageMode.imageTopic is not set");
        } else {
          needTopic(panel, image.imageTopic, IMAGE_SCHEMAS, "image");
        }
        if (image.calibrationTopic != undefined) {
          needTopic(panel, image.calibrationTopic, CALIBRATION_SCHEMAS, "calibration");
        }
      }
      if (image.annotations != undefined) {
        if (typeof image.annotations !== "object" || Array.isArray(image.annotations)) {
          problem(panel, "imageMode.annotations must be an object {topic: {visible: bool}}");
        } else {
          for (const [topic, settings] of Object.entries(image.annotations)) {
            needTopic(panel, topic, ANNOTATION_SCHEMAS, "annotation");
            if (typeof settings?.visible !== "boolean") {
              problem(panel, `imageMode.annotations["${topic}"].visible must be a boolean`);
            }
          }
        }
      }
      if (config.followTf != undefined && !log.frames.has(config.followTf)) {
        problem(panel, `followTf "${config.followTf}" is not a frame in the log's transforms`);
      } else if (config.followTf != undefined) {
        // The 3D panel always subscribes to every transform topic.
        for (const [topic, t] of log.topics) {
          if (TRANSFORM_SCHEMAS.has(t.schema)) {
            referenced.add(topic);
          }
        }
      }
      for (const [topic, settings] of Object.entries(config.topics ?? {})) {
        needTopic(panel, topic, undefined, "3D");
        if (settings != undefined && typeof settings !== "object") {
          problem(panel, `topics["${topic}"] must be an object`);
        }
      }
      for (const key of Object.keys(config.transforms ?? {})) {
        if (!key.startsWith("frame:")) {
          problem(panel, `transforms["${key}"]: keys there are "frame:<frame id>"; global transform settings belong in scene.transforms`);
        } else if (!log.frames.has(key.slice(6))) {
          warn(panel, `transforms["${key}"] names a frame the log does not have`);
        }
      }
      for (const key of Object.keys(config.scene?.transforms ?? {})) {
        if (!SCENE_TRANSFORM_KEYS.has(key)) {
          problem(panel, `scene.transforms.${key} is not a setting the 3D panel reads`);
        }
      }
    } else if (type === "Plot") {
      if (!Array.isArray(config.paths) || config.paths.length === 0) {
        problem(panel, "paths must be a non-empty array");
      }
      if (config.xAxisVal != undefined && !X_AXIS_VALS.has(config.xAxisVal)) {
        problem(panel, `xAxisVal ${JSON.stringify(config.xAxisVal)}`);
      }
      for (const p of config.paths ?? []) {
        if (typeof p.value !== "string" || typeof p.enabled !== "boolean" || !TIMESTAMP_METHODS.has(p.timestampMethod)) {
          problem(panel, `path ${JSON.stringify(p)} needs value (string), enabled (bool), timestampMethod (receiveTime|headerStamp)`);
          continue;
        }
        const parsed = parseMessagePath(p.value);
        if (parsed == undefined || parsed.names.length === 0) {
          problem(panel, `path ${p.value} is not "<topic>.<field>" in the app's message-path syntax`);
          continue;
        }
        needTopic(panel, parsed.topic, undefined, "plot");
        const t = log.topics.get(parsed.topic);
        const fields = t?.datatypes?.get(t.schema);
        if (t != undefined && t.encoding === "json") {
          const type = parsed.names.length === 1 ? fields?.get(parsed.names[0]) : undefined;
          if (type !== "number" && type !== "integer") {
            problem(panel, `path ${p.value}: the channel's schema has no numeric field ${parsed.names.join(".")}`);
          }
        }
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------

async function main(argv) {
  if (argv.length < 1 || argv.length > 2 || argv[0].startsWith("-")) {
    console.error("usage: node check.mjs RUN/log.mcap [RUN/foxglove_layout.json]");
    return 2;
  }
  const [logPath, layoutPath] = argv;
  let log;
  try {
    log = await checkLog(logPath);
  } catch (err) {
    problem(logPath, `cannot be read: ${err.message}`);
  }
  const referenced = new Set();
  if (layoutPath != undefined) {
    try {
      const layout = JSON.parse(await readFile(layoutPath, "utf8"));
      checkLayout(layout, log ?? { topics: new Map(), frames: new Set() }, referenced);
    } catch (err) {
      problem(layoutPath, `cannot be read as JSON: ${err.message}`);
    }
  }
  if (log) {
    console.log(`${logPath}: ${log.stream.messages.length} messages, ${log.stream.chunks.length} zstd chunks, ` +
      `${log.stream.channels.size} channels, summary ${log.indexed ? "read by the indexed reader" : "NOT readable"}`);
    const rows = [...log.topics].sort(([a], [b]) => a.localeCompare(b));
    const width = Math.max(...rows.map(([topic]) => topic.length), 5);
    console.log(`${"topic".padEnd(width)}  ${"schema".padEnd(28)} ${"encoding".padEnd(8)} ${"count".padStart(5)}  log time s      in layout`);
    for (const [topic, t] of rows) {
      const span = t.first == undefined ? "-" : `${(Number(t.first) / 1e9).toFixed(3)}..${(Number(t.last) / 1e9).toFixed(3)}`;
      console.log(`${topic.padEnd(width)}  ${t.schema.padEnd(28)} ${t.encoding.padEnd(8)} ${String(t.count).padStart(5)}  ${span.padEnd(15)} ${referenced.has(topic) ? "yes" : ""}`);
    }
    console.log(`annotation points: ${log.pointsTotal}; transform frames: ${[...log.frames].sort().join(", ")}`);
  }
  const more = (n) => (n > 1 ? ` (and ${n - 1} more like it)` : "");
  for (const { text, count } of warnings.values()) {
    console.log(`warning: ${text}${more(count)}`);
  }
  let total = 0;
  for (const { text, count } of problems.values()) {
    console.log(`PROBLEM: ${text}${more(count)}`);
    total += count;
  }
  console.log(total === 0 ? "OK: no problems" : `${total} problem(s)`);
  return total === 0 ? 0 : 1;
}

process.exitCode = await main(process.argv.slice(2));
