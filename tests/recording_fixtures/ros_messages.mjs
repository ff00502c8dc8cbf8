// The message types of the fixture content table: their definitions (ROS 1 and ROS 2 .msg text,
// concatenated with their dependencies as `gendeps --cat` and rosbag2 do) and the message objects
// @foxglove/rosmsg-serialization (ROS 1) and @foxglove/rosmsg2-serialization (CDR) serialize.
import rosmsg from "@foxglove/rosmsg";
import ros1Serialization from "@foxglove/rosmsg-serialization";
import ros2Serialization from "@foxglove/rosmsg2-serialization";
import cdrWriterModule from "@foxglove/cdr/dist/CdrWriter.js";
import cdr from "@foxglove/cdr";

const SEPARATOR = "=".repeat(80);
const join = (main, deps) => [main, ...deps.map(([name, text]) => `${SEPARATOR}\nMSG: ${name}\n${text}`)].join("\n");

const POINT_FIELD = `uint8 INT8    = 1
uint8 UINT8   = 2
uint8 INT16   = 3
uint8 UINT16  = 4
uint8 INT32   = 5
uint8 UINT32  = 6
uint8 FLOAT32 = 7
uint8 FLOAT64 = 8
string name
uint32 offset
uint8  datatype
uint32 count`;
const VECTOR3 = "float64 x\nfloat64 y\nfloat64 z";
const QUATERNION = "float64 x\nfloat64 y\nfloat64 z\nfloat64 w";
const TRANSFORM = "geometry_msgs/Vector3 translation\ngeometry_msgs/Quaternion rotation";
const POSE = "geometry_msgs/Point position\ngeometry_msgs/Quaternion orientation";
const ROI = "uint32 x_offset\nuint32 y_offset\nuint32 height\nuint32 width\nbool do_rectify";

function definitions(ros2) {
  const header = ros2
    ? [["std_msgs/Header", "builtin_interfaces/Time stamp\nstring frame_id"], ["builtin_interfaces/Time", "int32 sec\nuint32 nanosec"]]
    : [["std_msgs/Header", "uint32 seq\ntime stamp\nstring frame_id"]];
  const H = "std_msgs/Header header";
  const camera = ros2
    ? "string distortion_model\nfloat64[] d\nfloat64[9] k\nfloat64[9] r\nfloat64[12] p"
    : "string distortion_model\nfloat64[] D\nfloat64[9] K\nfloat64[9] R\nfloat64[12] P";
  return {
    "sensor_msgs/PointCloud2": join(
      `${H}\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\nbool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense`,
      [...header, ["sensor_msgs/PointField", POINT_FIELD]]),
    "sensor_msgs/CompressedImage": join(`${H}\nstring format\nuint8[] data`, header),
    "sensor_msgs/Image": join(`${H}\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\nuint32 step\nuint8[] data`, header),
    "sensor_msgs/CameraInfo": join(
      `${H}\nuint32 height\nuint32 width\n${camera}\nuint32 binning_x\nuint32 binning_y\nsensor_msgs/RegionOfInterest roi`,
      [...header, ["sensor_msgs/RegionOfInterest", ROI]]),
    "tf2_msgs/TFMessage": join("geometry_msgs/TransformStamped[] transforms", [
      ["geometry_msgs/TransformStamped", `${H}\nstring child_frame_id\ngeometry_msgs/Transform transform`],
      ...header,
      ["geometry_msgs/Transform", TRANSFORM],
      ["geometry_msgs/Vector3", VECTOR3],
      ["geometry_msgs/Quaternion", QUATERNION],
    ]),
    "nav_msgs/Odometry": join(
      `${H}\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\ngeometry_msgs/TwistWithCovariance twist`, [
        ...header,
        ["geometry_msgs/PoseWithCovariance", "geometry_msgs/Pose pose\nfloat64[36] covariance"],
        ["geometry_msgs/Pose", POSE],
        ["geometry_msgs/Point", VECTOR3],
        ["geometry_msgs/Quaternion", QUATERNION],
        ["geometry_msgs/TwistWithCovariance", "geometry_msgs/Twist twist\nfloat64[36] covariance"],
        ["geometry_msgs/Twist", "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular"],
        ["geometry_msgs/Vector3", VECTOR3],
      ]),
  };
}

export const TYPE_OF_KIND = {
  cloud: "sensor_msgs/PointCloud2",
  jpeg: "sensor_msgs/CompressedImage",
  camera_info: "sensor_msgs/CameraInfo",
  label: "sensor_msgs/Image",
  tf: "tf2_msgs/TFMessage",
  odom: "nav_msgs/Odometry",
};

// ROS 2 type names carry "msg": sensor_msgs/msg/PointCloud2.
export const ros2Name = (type) => type.replace("/", "/msg/");

const time = (ns) => ({ sec: Number(ns / 1000000000n), nsec: Number(ns % 1000000000n) });

function cloudData(c) {
  const points = c.xyzi.length / 16;
  const step = 20 + c.padding;
  const data = Buffer.alloc(points * step);
  for (let i = 0; i < points; ++i) {
    c.xyzi.copy(data, i * step, i * 16, i * 16 + 16);
    data.writeUInt32LE(c.times ? c.times.readUInt32LE(i * 4) : 0, i * step + 16);
  }
  const height = c.organised > 0 ? c.organised : 1;
  if (points % height !== 0) throw new Error(`--organised ${height}: ${points} points are not ${height} rows`);
  const field = (name, offset, datatype) => ({ name, offset, datatype, count: 1 });
  return {
    height, width: points / height,
    fields: [field("x", 0, 7), field("y", 4, 7), field("z", 8, 7), field("intensity", 12, 7), field("t", 16, 6)],
    is_bigendian: false, point_step: step, row_step: (points / height) * step, data, is_dense: true,
  };
}

// The message object of one neutral message (sequence.mjs) for ROS 1 (ros2 = false) or ROS 2.
export function messageObject(m, ros2) {
  const header = (frame_id) => ({ seq: 0, stamp: time(m.stamp), frame_id });
  const c = m.content;
  switch (m.kind) {
    case "cloud": return { header: header("os1_sensor"), ...cloudData(c) };
    case "jpeg": return { header: header("pylon_camera"), format: "jpeg", data: c.jpeg };
    case "label":
      return { header: header("pylon_camera"), height: c.height, width: c.width, encoding: "mono8", is_bigendian: 0, step: c.width, data: c.pixels };
    case "camera_info": {
      const K = [c.fx, 0, c.cx, 0, c.fy, c.cy, 0, 0, 1];
      const R = [1, 0, 0, 0, 1, 0, 0, 0, 1];
      const P = [c.fx, 0, c.cx, 0, 0, c.fy, c.cy, 0, 0, 0, 1, 0];
      const matrices = ros2 ? { d: c.distortion, k: K, r: R, p: P } : { D: c.distortion, K, R, P };
      return {
        header: header("pylon_camera"), height: c.height, width: c.width, distortion_model: "plumb_bob", ...matrices,
        binning_x: 0, binning_y: 0, roi: { x_offset: 0, y_offset: 0, height: 0, width: 0, do_rectify: false },
      };
    }
    case "tf":
      return { transforms: [{ header: header(c.parent), child_frame_id: c.child, transform: { translation: c.translation, rotation: c.rotation } }] };
    case "odom": {
      const zero = { x: 0, y: 0, z: 0 };
      return {
        header: header("map"), child_frame_id: "os1_sensor",
        pose: { pose: { position: c.translation, orientation: c.rotation }, covariance: new Array(36).fill(0) },
        twist: { twist: { linear: zero, angular: zero }, covariance: new Array(36).fill(0) },
      };
    }
  }
  throw new Error(`unknown message kind ${m.kind}`);
}

// Big-endian CDR: @foxglove/rosmsg2-serialization always asks @foxglove/cdr for little-endian; its
// CdrWriter takes the encapsulation kind as an option, so the writer it constructs is swapped for
// one that asks for CDR_BE (the serializer's own code does the rest).
let bigEndianInstalled = false;
function useBigEndianCdr() {
  if (bigEndianInstalled) return;
  const Original = cdrWriterModule.CdrWriter;
  cdrWriterModule.CdrWriter = class extends Original {
    constructor(options = {}) {
      super({ ...options, kind: cdr.EncapsulationKind.CDR_BE });
    }
  };
  bigEndianInstalled = true;
}

// serializer(type) -> (object) => Uint8Array, with the definition text and its md5 (ROS 1).
export function makeSerializers(ros2, bigEndian = false) {
  if (bigEndian) {
    if (!ros2) throw new Error("--big-endian applies to CDR (ROS 2) only");
    useBigEndianCdr();
  }
  const texts = definitions(ros2);
  const cache = new Map();
  return (type) => {
    if (!cache.has(type)) {
      const text = texts[type];
      const parsed = rosmsg.parse(text, { ros2 });
      const writer = ros2 ? new ros2Serialization.MessageWriter(parsed) : new ros1Serialization.MessageWriter(parsed);
      cache.set(type, { text, md5: ros2 ? "" : rosmsg.md5(parsed), write: (o) => writer.writeMessage(o) });
    }
    return cache.get(type);
  };
}
