#!/usr/bin/env python3
"""Reads a TensorBoard event file independently of hlt's writer and prints its scalars as `step,tag,value`.

The check for hlt::EventFileWriter: records are framed and checksummed as TFRecord defines (CRCs verified
with the `crc32c` module), and each Event is decoded by Debian's protobuf runtime against TensorFlow's
Event/Summary schema, rebuilt here from descriptors because TensorFlow itself is not installable. Exits 1
with a message on stderr for any defect: a bad CRC, a cut-off record, a first record that is not
`file_version: "brain.Event:2"`, a summary value that is not a simple_value, bytes the schema cannot parse.

Usage: read_tfevents.py EVENT_FILE
"""
import struct
import sys

import crc32c
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

F = descriptor_pb2.FieldDescriptorProto


def event_class():
    """tensorflow.Event with the fields TensorBoard's scalar plugin reads (tensorflow/core/util/event.proto,
    tensorflow/core/framework/summary.proto), field numbers and types as there."""
    proto = descriptor_pb2.FileDescriptorProto(name="hlt_tfevents.proto", package="tensorflow", syntax="proto3")

    summary = proto.message_type.add(name="Summary")
    value = summary.nested_type.add(name="Value")
    value.oneof_decl.add(name="value")
    value.field.add(name="tag", number=1, type=F.TYPE_STRING, label=F.LABEL_OPTIONAL)
    value.field.add(name="simple_value", number=2, type=F.TYPE_FLOAT, label=F.LABEL_OPTIONAL, oneof_index=0)
    summary.field.add(name="value", number=1, type=F.TYPE_MESSAGE, label=F.LABEL_REPEATED,
                      type_name=".tensorflow.Summary.Value")

    event = proto.message_type.add(name="Event")
    event.oneof_decl.add(name="what")
    event.field.add(name="wall_time", number=1, type=F.TYPE_DOUBLE, label=F.LABEL_OPTIONAL)
    event.field.add(name="step", number=2, type=F.TYPE_INT64, label=F.LABEL_OPTIONAL)
    event.field.add(name="file_version", number=3, type=F.TYPE_STRING, label=F.LABEL_OPTIONAL, oneof_index=0)
    event.field.add(name="summary", number=5, type=F.TYPE_MESSAGE, label=F.LABEL_OPTIONAL,
                    type_name=".tensorflow.Summary", oneof_index=0)

    pool = descriptor_pool.DescriptorPool()
    pool.Add(proto)
    descriptor = pool.FindMessageTypeByName("tensorflow.Event")
    if hasattr(message_factory, "GetMessageClass"):  # protobuf >= 4.22
        return message_factory.GetMessageClass(descriptor)
    return message_factory.MessageFactory(pool).GetPrototype(descriptor)


def masked_crc(data):
    crc = crc32c.crc32c(data)
    return ((((crc >> 15) | (crc << 17)) & 0xFFFFFFFF) + 0xA282EAD8) & 0xFFFFFFFF


def fail(message):
    print(f"read_tfevents: {message}", file=sys.stderr)
    sys.exit(1)


def records(path):
    with open(path, "rb") as f:
        content = f.read()
    at = 0
    while at < len(content):
        if len(content) - at < 12:
            fail(f"{path}: record header cut off at byte {at}")
        length_bytes = content[at:at + 8]
        (length,) = struct.unpack("<Q", length_bytes)
        (length_crc,) = struct.unpack("<I", content[at + 8:at + 12])
        if length_crc != masked_crc(length_bytes):
            fail(f"{path}: length CRC mismatch at byte {at}")
        if len(content) - at - 12 < length + 4:
            fail(f"{path}: record cut off at byte {at}")
        data = content[at + 12:at + 12 + length]
        (data_crc,) = struct.unpack("<I", content[at + 12 + length:at + 16 + length])
        if data_crc != masked_crc(data):
            fail(f"{path}: data CRC mismatch at byte {at}")
        yield at, data
        at += 16 + length


def main():
    if len(sys.argv) != 2:
        fail("usage: read_tfevents.py EVENT_FILE")
    path = sys.argv[1]
    Event = event_class()
    for i, (at, data) in enumerate(records(path)):
        try:
            event = Event.FromString(data)
        except Exception as e:  # the runtime's DecodeError
            fail(f"{path}: record at byte {at} is not an Event: {e}")
        if event.wall_time < 1e9:
            fail(f"{path}: record at byte {at} has wall_time {event.wall_time}, not a Unix time")
        kind = event.WhichOneof("what")
        if i == 0:
            if kind != "file_version" or event.file_version != "brain.Event:2":
                fail(f"{path}: first record is not file_version brain.Event:2 ({event})")
            continue
        if kind != "summary":
            fail(f"{path}: record at byte {at} holds {kind}, expected a summary")
        for value in event.summary.value:
            if value.WhichOneof("value") != "simple_value":
                fail(f"{path}: record at byte {at}: tag {value.tag} has no simple_value")
            print(f"{event.step},{value.tag},{value.simple_value!r}")


if __name__ == "__main__":
    main()
