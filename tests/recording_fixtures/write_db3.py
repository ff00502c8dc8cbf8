#!/usr/bin/env python3
"""Writes one rosbag2 sqlite3 storage file (.db3) with Python's standard sqlite3 module, for
write_rosbag2.mjs (Node has no SQLite). The tables are rosbag2's: schema version 3 (Humble: schema,
metadata, topics, messages) or 4 (Iron and later: topics.type_description_hash and a
message_definitions table), with the timestamp index rosbag2 creates.

usage: write_db3.py OUT.db3 SCHEMA_VERSION ROS_DISTRO < input
input: one line of JSON {"topics": [...], "definitions": [...]}, then records of
<uint32 topic id><int64 timestamp ns><uint32 size><size bytes of data>, little-endian."""
import json
import os
import sqlite3
import struct
import sys


def main():
    if len(sys.argv) != 4 or sys.argv[2] not in ("3", "4"):
        print(__doc__, file=sys.stderr)
        return 2
    out, version, distro = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    if os.path.exists(out):
        print(f"write_db3.py: {out} already exists", file=sys.stderr)
        return 1
    stdin = sys.stdin.buffer
    spec = json.loads(stdin.readline())
    db = sqlite3.connect(out)
    db.execute("CREATE TABLE schema(schema_version INTEGER PRIMARY KEY,ros_distro TEXT NOT NULL);")
    db.execute("CREATE TABLE metadata(id INTEGER PRIMARY KEY,metadata_version INTEGER NOT NULL,metadata TEXT NOT NULL);")
    if version >= 4:
        db.execute("CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
                   "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL,"
                   "type_description_hash TEXT NOT NULL);")
        db.execute("CREATE TABLE message_definitions(id INTEGER PRIMARY KEY,topic_type TEXT NOT NULL,"
                   "encoding TEXT NOT NULL,encoded_message_definition TEXT NOT NULL,"
                   "type_description_hash TEXT NOT NULL);")
    else:
        db.execute("CREATE TABLE topics(id INTEGER PRIMARY KEY,name TEXT NOT NULL,type TEXT NOT NULL,"
                   "serialization_format TEXT NOT NULL,offered_qos_profiles TEXT NOT NULL);")
    db.execute("CREATE TABLE messages(id INTEGER PRIMARY KEY,topic_id INTEGER NOT NULL,"
               "timestamp INTEGER NOT NULL, data BLOB NOT NULL);")
    db.execute("CREATE INDEX timestamp_idx ON messages (timestamp ASC);")
    db.execute("INSERT INTO schema (schema_version, ros_distro) VALUES (?, ?)", (version, distro))
    for t in spec["topics"]:
        if version >= 4:
            db.execute("INSERT INTO topics (id, name, type, serialization_format, offered_qos_profiles, "
                       "type_description_hash) VALUES (?, ?, ?, ?, ?, ?)",
                       (t["id"], t["name"], t["type"], t["serialization_format"], t["offered_qos_profiles"],
                        t.get("type_description_hash", "")))
        else:
            db.execute("INSERT INTO topics (id, name, type, serialization_format, offered_qos_profiles) "
                       "VALUES (?, ?, ?, ?, ?)",
                       (t["id"], t["name"], t["type"], t["serialization_format"], t["offered_qos_profiles"]))
    if version >= 4:
        for d in spec["definitions"]:
            db.execute("INSERT INTO message_definitions (topic_type, encoding, encoded_message_definition, "
                       "type_description_hash) VALUES (?, ?, ?, ?)",
                       (d["topic_type"], d["encoding"], d["encoded_message_definition"], ""))
    while True:
        head = stdin.read(16)
        if not head:
            break
        if len(head) != 16:
            raise SystemExit("write_db3.py: truncated record header on stdin")
        topic_id, timestamp, size = struct.unpack("<IqI", head)
        data = stdin.read(size)
        if len(data) != size:
            raise SystemExit("write_db3.py: truncated record on stdin")
        db.execute("INSERT INTO messages (timestamp, topic_id, data) VALUES (?, ?, ?)", (timestamp, topic_id, data))
    if "metadata" in spec:
        db.execute("INSERT INTO metadata (metadata_version, metadata) VALUES (?, ?)",
                   (spec["metadata_version"], spec["metadata"]))
    db.commit()
    db.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
