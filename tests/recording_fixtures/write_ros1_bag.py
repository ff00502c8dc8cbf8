#!/usr/bin/python3
"""Writes a RELLIS-3D-layout sequence (as `slamvdb synth` makes it) as a ROS 1 bag, with ROS's own
bag writer (Debian's python3-rosbag) and message classes (python3-sensor-msgs, -geometry-msgs,
-nav-msgs, -tf2-msgs): fixtures for slamvdb's bag reader made by a writer that is not slamvdb's.
The content is the one every recording fixture writer shares (the MCAP and rosbag2 writers write
the same messages): PointCloud2 scans with per-point t, CompressedImage, CameraInfo, a mono8 label
Image, /tf_static and ground-truth Odometry. Run with Debian's interpreter: /usr/bin/python3 write_ros1_bag.py ...

--manifest FILE writes JSON lines, one per message in the order written: its topic, type, log time,
header stamp, size and the CRC-32 (zlib's) of its serialized bytes, so that a reader can be checked
message by message (the same manifest as the MCAP and rosbag2 fixture writers'); with --kill-after,
"in_finished_chunk" says whether the message's chunk was finished before the writer stopped.
--no-index and --kill-after N leave the bag as a recording that was not closed leaves it."""
import argparse
import io
import json
import os
import re
import struct
import sys
import zlib

import genpy
import numpy as np
import rosbag
import yaml
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import CameraInfo, CompressedImage, Image, PointCloud2, PointField
from tf2_msgs.msg import TFMessage

IMAGE_NAME = re.compile(r"frame(\d+)-(\d+)_(\d+)\.(jpg|png)$")


def fail(message):
    print(f"write_ros1_bag.py: {message}", file=sys.stderr)
    sys.exit(1)


def stamp_of(ns):
    return genpy.Time(ns // 1_000_000_000, ns % 1_000_000_000)


def seconds_to_ns(text):
    whole, _, frac = text.strip().partition(".")
    return int(whole) * 1_000_000_000 + int((frac + "000000000")[:9])


def png_gray8(path):
    """Decodes an 8-bit greyscale, non-interlaced PNG (what synth writes for labels)."""
    data = open(path, "rb").read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        fail(f"{path} is not a PNG file")
    pos, idat, width = 8, b"", None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            width, height, depth, colour, _, _, interlace = struct.unpack(">IIBBBBB", body)
            if depth != 8 or colour != 0 or interlace != 0:
                fail(f"{path}: only 8-bit greyscale non-interlaced PNGs are read (depth {depth}, colour type {colour})")
        elif kind == b"IDAT":
            idat += body
        pos += 12 + length
    raw = zlib.decompress(idat)
    rows, prev = [], bytearray(width)
    for r in range(height):
        line = raw[r * (width + 1):(r + 1) * (width + 1)]
        kind, cur = line[0], bytearray(line[1:])
        for i in range(width):
            a = cur[i - 1] if i > 0 else 0
            b = prev[i]
            c = prev[i - 1] if i > 0 else 0
            if kind == 1:
                cur[i] = (cur[i] + a) & 255
            elif kind == 2:
                cur[i] = (cur[i] + b) & 255
            elif kind == 3:
                cur[i] = (cur[i] + (a + b) // 2) & 255
            elif kind == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                cur[i] = (cur[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        rows.append(bytes(cur))
        prev = cur
    return width, height, b"".join(rows)


def quaternion_xyzw(R):
    """A rotation matrix as a unit quaternion (x, y, z, w), Shepperd's method."""
    t = R[0][0] + R[1][1] + R[2][2]
    if t > 0:
        s = 2.0 * (1.0 + t) ** 0.5
        return ((R[2][1] - R[1][2]) / s, (R[0][2] - R[2][0]) / s, (R[1][0] - R[0][1]) / s, 0.25 * s)
    i = max(range(3), key=lambda k: R[k][k])
    j, k = (i + 1) % 3, (i + 2) % 3
    s = 2.0 * (1.0 + R[i][i] - R[j][j] - R[k][k]) ** 0.5
    q = [0.0, 0.0, 0.0]
    q[i] = 0.25 * s
    q[j] = (R[j][i] + R[i][j]) / s
    q[k] = (R[k][i] + R[i][k]) / s
    return (q[0], q[1], q[2], (R[k][j] - R[j][k]) / s)


def read_sequence(folder, max_scans):
    times = [seconds_to_ns(l) for l in open(os.path.join(folder, "times.txt")) if l.strip()]
    scan_dir = os.path.join(folder, "os1_cloud_node_kitti_bin")
    scans = sorted(f for f in os.listdir(scan_dir) if f.endswith(".bin"))
    if len(scans) != len(times):
        fail(f"{folder}: {len(scans)} scans but {len(times)} times")
    poses = [[float(v) for v in l.split()] for l in open(os.path.join(folder, "poses.txt")) if l.strip()]
    if max_scans is not None:
        scans, times, poses = scans[:max_scans], times[:max_scans], poses[:max_scans]
    cam = [[float(v) for v in l.split()] for l in open(os.path.join(folder, "camera_info.txt")) if l.strip()]
    transform = next(iter(yaml.safe_load(open(os.path.join(folder, "transforms.yaml"))).values()))
    images = []
    for name in sorted(os.listdir(os.path.join(folder, "pylon_camera_node"))):
        m = IMAGE_NAME.match(name)
        if m:
            ns = int(m.group(2)) * 1_000_000_000 + int(m.group(3)) * 1_000_000
            if max_scans is None or ns <= times[-1]:
                images.append((ns, name))
    return [os.path.join(scan_dir, s) for s in scans], times, poses, cam, transform, images


def cloud_message(path, stamp_ns, organised, padding, times_dir):
    points = np.fromfile(path, dtype="<f4").reshape(-1, 4)
    n = len(points)
    times = np.zeros(n, dtype="<u4")
    if times_dir:  # one uint32 (ns since the scan start) per point, in a file named like the scan
        times_path = os.path.join(times_dir, os.path.basename(path))
        if not os.path.isfile(times_path):
            fail(f"{times_path}: no per-point times for {path}")
        times = np.fromfile(times_path, dtype="<u4")
        if len(times) != n:
            fail(f"{times_path}: {len(times)} times for {n} points (one uint32 per point expected)")
    height = organised or 1
    if n % height:
        fail(f"{path}: {n} points do not make {height} rows")
    step = 20 + padding
    record = np.zeros(n, dtype=np.dtype({"names": ["x", "y", "z", "intensity", "t"],
                                         "formats": ["<f4", "<f4", "<f4", "<f4", "<u4"],
                                         "offsets": [0, 4, 8, 12, 16], "itemsize": step}))
    for i, name in enumerate(["x", "y", "z", "intensity"]):
        record[name] = points[:, i]
    record["t"] = times
    msg = PointCloud2()
    msg.header.stamp = stamp_of(stamp_ns)
    msg.header.frame_id = "os1_sensor"
    msg.height, msg.width = height, n // height
    msg.fields = [PointField(name=name, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, name in enumerate(["x", "y", "z", "intensity"])]
    msg.fields.append(PointField(name="t", offset=16, datatype=PointField.UINT32, count=1))
    msg.is_bigendian, msg.is_dense = False, True
    msg.point_step, msg.row_step = step, step * msg.width
    msg.data = record.tobytes()
    return msg


def build_messages(args):
    """Every message as (topic, ROS type, message, stamp ns), in time order (the order written)."""
    scans, times, poses, cam, transform, images = read_sequence(args.sequence, args.max_scans)
    out = []
    tf = TransformStamped()
    tf.header.stamp = stamp_of(times[0])
    tf.header.frame_id, tf.child_frame_id = "os1_sensor", "pylon_camera"
    q, t = transform["q"], transform["t"]
    tf.transform.translation.x, tf.transform.translation.y, tf.transform.translation.z = t["x"], t["y"], t["z"]
    r = tf.transform.rotation
    r.x, r.y, r.z, r.w = q["x"], q["y"], q["z"], q["w"]
    out.append(("/tf_static", args.tf_type, TFMessage(transforms=[tf]), times[0]))
    events = [(ns, 0, i) for i, ns in enumerate(times)] + [(ns, 1, i) for i, (ns, _) in enumerate(images)]
    for ns, kind, i in sorted(events):
        if kind == 0:
            out.append(("/os1_cloud_node/points", "sensor_msgs/PointCloud2",
                        cloud_message(scans[i], ns, args.organised, args.padding, args.point_times), ns))
            odom = Odometry()
            odom.header.stamp = stamp_of(ns)
            odom.header.frame_id, odom.child_frame_id = "map", "os1_sensor"
            p = poses[i]
            R = [p[0:3], p[4:7], p[8:11]]
            o = odom.pose.pose
            o.position.x, o.position.y, o.position.z = p[3], p[7], p[11]
            o.orientation.x, o.orientation.y, o.orientation.z, o.orientation.w = quaternion_xyzw(R)
            out.append(("/ground_truth/odom", "nav_msgs/Odometry", odom, ns))
            continue
        name = images[i][1]
        jpeg = open(os.path.join(args.sequence, "pylon_camera_node", name), "rb").read()
        label_path = os.path.join(args.sequence, "pylon_camera_node_label_id", name[:-4] + ".png")
        width, height, labels = png_gray8(label_path)
        compressed = CompressedImage(format="jpeg", data=jpeg)
        compressed.header.stamp, compressed.header.frame_id = stamp_of(ns), "pylon_camera"
        out.append(("/pylon_camera_node/image_raw/compressed", "sensor_msgs/CompressedImage", compressed, ns))
        info = CameraInfo(width=width, height=height, distortion_model="plumb_bob")
        info.header.stamp, info.header.frame_id = stamp_of(ns), "pylon_camera"
        fx, fy, cx, cy = cam[0][:4]
        info.D = list(cam[1][:5]) if len(cam) > 1 else [0.0] * 5
        info.K = [fx, 0, cx, 0, fy, cy, 0, 0, 1]
        info.R = [1, 0, 0, 0, 1, 0, 0, 0, 1]
        info.P = [fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0]
        out.append(("/pylon_camera_node/camera_info", "sensor_msgs/CameraInfo", info, ns))
        label = Image(height=height, width=width, encoding="mono8", is_bigendian=0, step=width, data=labels)
        label.header.stamp, label.header.frame_id = stamp_of(ns), "pylon_camera"
        out.append(("/pylon_camera_node_label_id/image", "sensor_msgs/Image", label, ns))
    if args.write_order == "topic":  # topic by topic: every chunk overlaps every other in time
        out.sort(key=lambda m: m[0])
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("sequence", help="sequence folder in the RELLIS-3D layout (slamvdb synth)")
    parser.add_argument("output", help="the .bag to write")
    parser.add_argument("--compression", choices=["none", "bz2", "lz4"], default="none")
    parser.add_argument("--chunk-size", type=int, default=768 * 1024, help="chunk threshold in bytes")
    parser.add_argument("--log-time-offset", type=float, default=0.0, help="log time = header stamp + S seconds")
    parser.add_argument("--max-scans", type=int, help="only the first K scans (and the images up to the last)")
    parser.add_argument("--organised", type=int, default=0, metavar="H", help="clouds of H rows")
    parser.add_argument("--padding", type=int, default=0, metavar="P", help="P bytes of padding after each point")
    parser.add_argument("--point-times", metavar="DIR",
                        help="per-point t from DIR/NNNNNN.bin (one uint32, ns since the scan start, per point)")
    parser.add_argument("--tf-type", choices=["tf2_msgs/TFMessage", "tf/tfMessage"], default="tf2_msgs/TFMessage")
    parser.add_argument("--write-order", choices=["time", "topic"], default="time",
                        help="time: as a recorder writes; topic: topic by topic (chunks overlapping in time)")
    parser.add_argument("--no-index", action="store_true",
                        help="stop without writing the index (chunks complete, index_pos 0), as a killed recording")
    parser.add_argument("--kill-after", type=int, metavar="N",
                        help="stop after N messages in the middle of a chunk, as a recorder killed while writing")
    parser.add_argument("--manifest", help="JSON file listing every message written")
    args = parser.parse_args()
    if not os.path.isdir(args.sequence):
        fail(f"{args.sequence} is not a folder")
    if args.padding < 0 or args.organised < 0 or args.chunk_size <= 0:
        fail("--padding, --organised and --chunk-size must be positive")
    messages = build_messages(args)
    offset_ns = round(args.log_time_offset * 1e9)
    bag = rosbag.Bag(args.output, "w", compression=args.compression, chunk_threshold=args.chunk_size)
    manifest, buffer, finished = [], io.BytesIO(), 0
    for seq, (topic, ros_type, msg, ns) in enumerate(messages):
        if args.kill_after is not None and seq >= args.kill_after:
            break
        buffer.seek(0)
        buffer.truncate()
        msg.serialize(buffer)
        data = buffer.getvalue()
        log_time = stamp_of(ns + offset_ns)
        chunks_before = len(bag._chunks)
        if ros_type == msg._type:
            bag.write(topic, msg, log_time)
        else:  # tf/tfMessage: the same layout and md5sum as tf2_msgs/TFMessage, under its ROS 1 name
            bag.write(topic, (ros_type, data, msg._md5sum, type(msg)), log_time, raw=True)
        if len(bag._chunks) > chunks_before:
            finished = seq + 1  # this message finished a chunk: it and all before it are in finished chunks
        manifest.append({"seq": seq, "topic": topic, "type": ros_type, "log_time_ns": ns + offset_ns,
                         "stamp_ns": ns, "size": len(data), "crc32": zlib.crc32(data)})
    if args.manifest:
        with open(args.manifest, "w") as f:
            for m in manifest:
                m["in_finished_chunk"] = args.kill_after is None or m["seq"] < finished
                f.write(json.dumps(m) + "\n")
    if args.no_index:
        bag.flush()  # the open chunk is finished and its index data written; the bag index is not
        bag._file.flush()
        os._exit(0)
    if args.kill_after is not None:
        bag._file.flush()  # what the writer had handed to the file; its compressor's state is lost
        os._exit(0)
    bag.close()


if __name__ == "__main__":
    main()
