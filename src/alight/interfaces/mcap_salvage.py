"""Read what is left of a ROS 2 MCAP bag that was cut short (a recorder killed mid-write: no summary, no
end magic), which rosbags' indexed reader refuses.

``McapSalvage`` reads the file from its start with the ``mcap`` package's stream reader, record by record,
until the first damaged or missing record, and offers the part of rosbags' ``AnyReader`` interface the
replay uses (``connections``, ``messages``, ``deserialize``, ``start_time``, ``end_time``,
``message_count``, ``close``). Messages are decoded with rosbags' ROS 2 Humble type store, which holds
every message type the replay accepts; per-message zstd compression (the bag's ``metadata.yaml`` says
``compression_mode: message``) is undone.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

RECORD_SIZE_LIMIT = 256 * 1024 * 1024
"""A record claiming more bytes than this (a damaged length) ends the salvage instead of an allocation."""


@dataclass(frozen=True)
class SalvagedConnection:
    id: int
    topic: str
    msgtype: str


class McapSalvage:
    """The readable prefix of a ROS 2 MCAP file, as a minimal ``AnyReader``."""

    def __init__(self, path: Path, *, zstd_messages: bool = False) -> None:
        from rosbags.typesys import Stores, get_typestore

        self.path = path
        self.zstd_messages = zstd_messages
        self._ts = get_typestore(Stores.ROS2_HUMBLE)
        self.connections: list[SalvagedConnection] = []
        self.message_count = 0
        self.start_time = 0
        self.end_time = 0
        self.stopped_by = ""
        """why the scan stopped before the end ('' when it read a complete file)"""
        by_id: dict[int, SalvagedConnection] = {}
        first: int | None = None
        last = 0
        for channel, log_time, _ in self._scan(by_id, None):
            del channel
            first = log_time if first is None else min(first, log_time)
            last = max(last, log_time)
            self.message_count += 1
        self.connections = list(by_id.values())
        self.start_time = first or 0
        self.end_time = last

    def _scan(
        self, by_id: dict[int, SalvagedConnection], wanted: set[int] | None
    ) -> Iterator[tuple[SalvagedConnection, int, bytes]]:
        from mcap.records import Channel, DataEnd, Footer, Message, Schema
        from mcap.stream_reader import StreamReader

        schemas: dict[int, str] = {}
        self.stopped_by = ""
        with open(self.path, "rb") as f:
            reader = StreamReader(f, record_size_limit=RECORD_SIZE_LIMIT)
            records = reader.records
            while True:
                try:
                    record = next(records)
                except StopIteration:
                    return
                except Exception as err:  # noqa: BLE001 - the first damaged record ends the salvage
                    self.stopped_by = f"{type(err).__name__}: {str(err)[:120]}"
                    return
                if isinstance(record, Schema):
                    schemas[record.id] = record.name
                elif isinstance(record, Channel):
                    if record.message_encoding == "cdr" and record.schema_id in schemas:
                        by_id.setdefault(
                            record.id, SalvagedConnection(record.id, record.topic, schemas[record.schema_id])
                        )
                elif isinstance(record, Message):
                    conn = by_id.get(record.channel_id)
                    if conn is not None and (wanted is None or conn.id in wanted):
                        yield conn, int(record.log_time), bytes(record.data)
                elif isinstance(record, DataEnd | Footer):
                    return

    def messages(
        self, connections: Sequence[SalvagedConnection] = ()
    ) -> Iterator[tuple[SalvagedConnection, int, bytes]]:
        """The messages of ``connections`` (all when empty), in file order."""
        wanted = {c.id for c in connections} if connections else None
        by_id = {c.id: c for c in self.connections}
        yield from self._scan(by_id, wanted)

    def deserialize(self, raw: bytes, msgtype: str) -> Any:
        if self.zstd_messages:
            import zstandard

            raw = zstandard.ZstdDecompressor().decompress(raw, max_output_size=RECORD_SIZE_LIMIT)
        return self._ts.deserialize_cdr(raw, msgtype)

    def close(self) -> None:
        pass
