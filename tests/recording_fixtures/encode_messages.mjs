#!/usr/bin/env node
// Serializes ROS messages described in JSON with encoders that are not slamvdb's, for the tests of
// slamvdb's message decoders: ROS 1 serialization by @foxglove/rosmsg-serialization, CDR by
// @foxglove/rosmsg2-serialization (little-endian as it writes it; big-endian by giving its CDR
// writer, @foxglove/cdr's CdrWriter, the CDR_BE encapsulation kind). The message definitions are
// the real ones of Debian's ROS 1 message packages (python3-sensor-msgs, ...), read through
// /usr/bin/python3; the ROS 2 form drops std_msgs/Header's seq (ROS 2 has none, and its time is
// builtin_interfaces/Time: int32 sec, uint32 nanosec).
//
//   node encode_messages.mjs IN.json OUT_DIR
// IN.json: {"messages": [{"name": N, "type": "sensor_msgs/PointCloud2", "message": {...},
//                         "cloud": {...} | "image": {...}}, ...]}
// writes OUT_DIR/N.ros1, N.cdr (little-endian) and N.cdr_be for each message. "message" holds the
// fields (times as {"sec", "nsec"}); "cloud" and "image" describe a PointCloud2's or Image's
// payload, packed here into `data` with DataView (see packCloud and packImage).
import { execFileSync } from "node:child_process";
import { mkdirSync, readFileSync, writeFileSync } from "node:fs";
import { createRequire } from "node:module";
import { join } from "node:path";

const require = createRequire(import.meta.url);
const { parse } = require("@foxglove/rosmsg");
const { MessageWriter: Ros1Writer } = require("@foxglove/rosmsg-serialization");
const { MessageWriter: Ros2Writer } = require("@foxglove/rosmsg2-serialization");
const cdrWriterModule = require("@foxglove/cdr/dist/CdrWriter");
const { EncapsulationKind } = require("@foxglove/cdr");

function usage(message) {
  process.stderr.write(`encode_messages.mjs: ${message}\nusage: node encode_messages.mjs IN.json OUT_DIR\n`);
  process.exit(2);
}

const args = process.argv.slice(2);
if (args.includes("--help") || args.includes("-h")) {
  process.stdout.write("usage: node encode_messages.mjs IN.json OUT_DIR (see the comment at the top)\n");
  process.exit(0);
}
if (args.length !== 2) usage("expected IN.json and OUT_DIR");
const [input, outDir] = args;
let spec;
try {
  spec = JSON.parse(readFileSync(input, "utf8"));
} catch (e) {
  usage(`cannot read ${input}: ${e.message}`);
}
if (!Array.isArray(spec.messages)) usage(`${input} has no "messages" array`);

// tf/tfMessage is ROS 1's name for the layout of tf2_msgs/TFMessage.
const definitionType = (type) => (type === "tf/tfMessage" ? "tf2_msgs/TFMessage" : type);

// The full definition text (the form bags carry) of each type, from Debian's generated classes.
function fullTexts(types) {
  const script = `
import importlib, json, sys
out = {}
for t in sys.argv[1:]:
    package, name = t.split("/")
    out[t] = getattr(importlib.import_module(package + ".msg"), name)._full_text
print(json.dumps(out))`;
  return JSON.parse(execFileSync("/usr/bin/python3", ["-c", script, ...types], { encoding: "utf8" }));
}

// ROS 2's form: std_msgs/Header without seq, and field names in lower case (ROS 2 requires them:
// CameraInfo's D K R P are d k r p there; the bytes are the same).
function ros2Text(type, text) {
  const sections = text.split(/\n=+\n/);
  return sections
    .map((section, i) =>
      /^MSG: std_msgs\/Header\n/.test(section) || (i === 0 && type === "std_msgs/Header")
        ? section.replace(/^uint32 seq.*$/m, "")
        : section,
    )
    .map((section) => section.replace(/^([\w/]+(?:\[\d*\])?\s+)([A-Z]\w*)(?=\s*(?:#|$))/gm, (_, type, name) => type + name.toLowerCase()))
    .join("\n================================================================================\n");
}
// The message with its keys in lower case, for the ROS 2 writer.
function lowerKeys(value) {
  if (Array.isArray(value)) return value.map(lowerKeys);
  if (value === null || typeof value !== "object" || ArrayBuffer.isView(value)) return value;
  return Object.fromEntries(Object.entries(value).map(([k, v]) => [k.toLowerCase(), lowerKeys(v)]));
}

const SIZES = { 1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 8: 8 };
function setScalar(view, offset, datatype, value, littleEndian) {
  switch (datatype) {
    case 1: return view.setInt8(offset, value);
    case 2: return view.setUint8(offset, value);
    case 3: return view.setInt16(offset, value, littleEndian);
    case 4: return view.setUint16(offset, value, littleEndian);
    case 5: return view.setInt32(offset, value, littleEndian);
    case 6: return view.setUint32(offset, value, littleEndian);
    case 7: return view.setFloat32(offset, value, littleEndian);
    case 8: return view.setFloat64(offset, value, littleEndian);
    default: throw new Error(`datatype ${datatype}`);
  }
}

// cloud: {fields: [{name, offset, datatype, count}], height, width, point_step, row_step?,
// is_bigendian, is_dense, points: [{name: value or "nan"}] (row-major), data_size?}. Bytes not
// covered by a field (padding) are 0xEE, so that a decoder reading them would see it.
function packCloud(message, cloud) {
  const rowStep = cloud.row_step ?? cloud.width * cloud.point_step;
  const size = cloud.data_size ?? cloud.height * rowStep;
  const data = new Uint8Array(size).fill(0xee);
  const view = new DataView(data.buffer);
  cloud.points.forEach((point, i) => {
    const base = Math.floor(i / cloud.width) * rowStep + (i % cloud.width) * cloud.point_step;
    for (const f of cloud.fields) {
      if (!(f.name in point) || base + f.offset + SIZES[f.datatype] > size) continue;
      const v = point[f.name] === "nan" ? NaN : point[f.name];
      setScalar(view, base + f.offset, f.datatype, v, !cloud.is_bigendian);
    }
  });
  Object.assign(message, {
    height: cloud.height, width: cloud.width, fields: cloud.fields, is_bigendian: cloud.is_bigendian,
    point_step: cloud.point_step, row_step: rowStep, data, is_dense: cloud.is_dense,
  });
}

// image: {encoding, width, height, step, is_bigendian, pixels: [[channel values]] (row-major),
// bytes_per_channel}; row padding is 0xAB.
function packImage(message, image) {
  const size = image.data_size ?? image.height * image.step;
  const data = new Uint8Array(size).fill(0xab);
  const view = new DataView(data.buffer);
  const channelBytes = image.bytes_per_channel ?? 1;
  image.pixels.forEach((channels, i) => {
    let offset = Math.floor(i / image.width) * image.step + (i % image.width) * channels.length * channelBytes;
    for (const v of channels) {
      if (offset + channelBytes > size) return;
      if (channelBytes === 2) view.setUint16(offset, v, !image.is_bigendian);
      else view.setUint8(offset, v);
      offset += channelBytes;
    }
  });
  Object.assign(message, {
    height: image.height, width: image.width, encoding: image.encoding, is_bigendian: image.is_bigendian ? 1 : 0,
    step: image.step, data,
  });
}

// @foxglove/cdr's writer with the big-endian encapsulation: rosmsg2-serialization creates its
// writer through this module's export, so replacing the export makes it write big-endian CDR.
const LittleEndianCdrWriter = cdrWriterModule.CdrWriter;
class BigEndianCdrWriter extends LittleEndianCdrWriter {
  constructor(options = {}) {
    super({ ...options, kind: EncapsulationKind.CDR_BE });
  }
}
function writeCdr(writer, message, bigEndian) {
  cdrWriterModule.CdrWriter = bigEndian ? BigEndianCdrWriter : LittleEndianCdrWriter;
  try {
    return writer.writeMessage(message);
  } finally {
    cdrWriterModule.CdrWriter = LittleEndianCdrWriter;
  }
}

const types = [...new Set(spec.messages.map((m) => definitionType(m.type)))];
const texts = fullTexts(types);
const writers = new Map(
  types.map((t) => [
    t,
    { ros1: new Ros1Writer(parse(texts[t])), ros2: new Ros2Writer(parse(ros2Text(t, texts[t]), { ros2: true })) },
  ]),
);
mkdirSync(outDir, { recursive: true });
for (const m of spec.messages) {
  const message = m.message ?? {};
  if (m.cloud) packCloud(message, m.cloud);
  if (m.image) packImage(message, m.image);
  const { ros1, ros2 } = writers.get(definitionType(m.type));
  writeFileSync(join(outDir, `${m.name}.ros1`), ros1.writeMessage(message));
  const ros2Message = lowerKeys(message);
  writeFileSync(join(outDir, `${m.name}.cdr`), writeCdr(ros2, ros2Message, false));
  const be = writeCdr(ros2, ros2Message, true);
  if (be[1] !== EncapsulationKind.CDR_BE) throw new Error("the big-endian CDR writer was not used");
  writeFileSync(join(outDir, `${m.name}.cdr_be`), be);
}
