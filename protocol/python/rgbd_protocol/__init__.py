"""Python codecs of the shared wire protocol (spec: protocol/spec/messages.json, docs/protocol.md).

Example:

    from rgbd_protocol import Codec, StreamDecoder
    codec = Codec()
    data = codec.encode("FrameRequest", {"credits": 1, "last_received_sequence": 41})
    dec = StreamDecoder(codec); dec.feed(data); event = dec.next()  # event.kind == "message"
"""

from .codec import (
    Codec,
    DecodeFailure,
    EncodeError,
    Event,
    StreamDecoder,
    event_view,
    normalize_events,
)
from .spec import Spec, load_spec

__all__ = [
    "Codec",
    "DecodeFailure",
    "EncodeError",
    "Event",
    "StreamDecoder",
    "event_view",
    "normalize_events",
    "Spec",
    "load_spec",
]
