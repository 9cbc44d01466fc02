"""Inputs: outside face data -> AU frames. Every source has ``.sample(t_s) -> AUFrame`` so it plugs into
``servoface.controller.performance.play_timeline(pipeline, source, duration_s)``.

Files (a :class:`Recording`): :func:`read_openface_csv`, :func:`read_pyfeat_csv`, :func:`read_jsonl`,
:func:`read_blendshape_csv`, :func:`read_fap`, or :func:`load_recording` (picks by file).
Live: :class:`StreamSource` fed by :class:`UdpReceiver`, :class:`TcpReceiver` or :class:`LineReceiver`.
Mapping: :func:`load_blendshape_map` (ARKit/MediaPipe -> AU prior), :func:`head_pose_aus`, :func:`mirror_aus`.
"""

from servoface.controller.inputs.assemble import ReadOptions
from servoface.controller.inputs.blendshapes import BlendshapeMap, load_blendshape_map
from servoface.controller.inputs.errors import InputError
from servoface.controller.inputs.face_files import read_blendshape_csv, read_jsonl
from servoface.controller.inputs.head_pose import head_pose_aus, matrix_to_ypr_deg
from servoface.controller.inputs.head_ranges import HeadRanges, fit_recording
from servoface.controller.inputs.loader import detect_format, load_recording
from servoface.controller.inputs.messages import Message, MessageDecoder
from servoface.controller.inputs.openface import read_openface_csv, read_pyfeat_csv
from servoface.controller.inputs.recorded import Recording
from servoface.controller.inputs.report import InputReport
from servoface.controller.inputs.shape_ranges import ShapeRanges
from servoface.controller.inputs.sides import mirror_aus
from servoface.controller.inputs.smoothing import AUSmoother, OneEuroFilter
from servoface.controller.inputs.stream import StreamSource, StreamStats
from servoface.controller.inputs.transports import LineReceiver, TcpReceiver, UdpReceiver

__all__ = [
    "AUSmoother",
    "BlendshapeMap",
    "HeadRanges",
    "InputError",
    "InputReport",
    "LineReceiver",
    "Message",
    "MessageDecoder",
    "OneEuroFilter",
    "ReadOptions",
    "Recording",
    "ShapeRanges",
    "StreamSource",
    "StreamStats",
    "TcpReceiver",
    "UdpReceiver",
    "detect_format",
    "fit_recording",
    "head_pose_aus",
    "load_blendshape_map",
    "load_recording",
    "matrix_to_ypr_deg",
    "mirror_aus",
    "read_blendshape_csv",
    "read_jsonl",
    "read_openface_csv",
    "read_pyfeat_csv",
]
