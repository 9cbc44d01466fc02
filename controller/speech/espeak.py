"""Text -> speech audio and phoneme events, through libespeak-ng's synthesis callback (ctypes).

No Python binding on PyPI exposes espeak-ng's phoneme events, so this is a thin ctypes layer over the five
calls of ``speak_lib.h`` that we need. The library and its voice data come from the ``espeakng-loader``
wheel (a PyPI package that bundles both), or else from Debian's ``libespeak-ng1`` + ``espeak-ng-data``.
Synthesis is synchronous (``AUDIO_OUTPUT_SYNCHRONOUS``): the callback receives every audio buffer and the
events that fall in it, each with its position in the output in ms and, from the buffer offsets, in
samples — so the phoneme times are exact by construction, in the audio's own clock.

espeak-ng keeps global state; one synthesis at a time per process (a lock guards it).
"""

from __future__ import annotations

import ctypes
import ctypes.util
import threading
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from servoface.controller.speech.errors import SpeechError, SynthesisUnavailableError

# speak_lib.h
_AUDIO_OUTPUT_SYNCHRONOUS = 2
_INITIALIZE_PHONEME_EVENTS = 0x0001
_INITIALIZE_DONT_EXIT = 0x8000
_CHARS_UTF8 = 1
_ENDPAUSE = 0x1000
_POS_CHARACTER = 1
_EVENT_LIST_TERMINATED = 0
_EVENT_WORD = 1
_EVENT_SENTENCE = 2
_EVENT_END = 5
_EVENT_MSG_TERMINATED = 6
_EVENT_PHONEME = 7
_PARAM_RATE = 1
_PARAM_VOLUME = 2
_PARAM_PITCH = 3

MAX_TEXT_CHARS = 20_000
RATE_WPM_RANGE = (80, 450)
PITCH_RANGE = (0, 99)


class _EventId(ctypes.Union):
    _fields_ = [("number", ctypes.c_int), ("name", ctypes.c_char_p), ("string", ctypes.c_char * 8)]


class _Event(ctypes.Structure):
    _fields_ = [
        ("type", ctypes.c_int),
        ("unique_identifier", ctypes.c_uint),
        ("text_position", ctypes.c_int),
        ("length", ctypes.c_int),
        ("audio_position", ctypes.c_int),
        ("sample", ctypes.c_int),
        ("user_data", ctypes.c_void_p),
        ("id", _EventId),
    ]


_CALLBACK = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.POINTER(_Event))


@dataclass(frozen=True)
class PhonemeEvent:
    """One phoneme as espeak-ng spoke it: its mnemonic (``p``, ``aI``, ``_:`` for a pause), start time in the
    audio (s) and the sample it starts at."""

    phoneme: str
    t_s: float
    sample: int


@dataclass(frozen=True)
class WordEvent:
    """A word's start in the audio and its place in the text (character offset and length)."""

    t_s: float
    text_position: int
    length: int


@dataclass(frozen=True)
class Synthesis:
    """Speech audio (mono int16 at ``sample_rate_hz``) with its phoneme and word events."""

    text: str
    voice: str
    samples: NDArray[np.int16]
    sample_rate_hz: int
    phonemes: tuple[PhonemeEvent, ...]
    words: tuple[WordEvent, ...]

    @property
    def duration_s(self) -> float:
        return len(self.samples) / self.sample_rate_hz

    def write_wav(self, path: str | Path) -> Path:
        from servoface.controller.speech.audio import write_wav

        return write_wav(path, self.samples, self.sample_rate_hz)


def _library_and_data() -> tuple[str, str | None]:
    try:
        import espeakng_loader

        return str(espeakng_loader.get_library_path()), str(espeakng_loader.get_data_path())
    except (ImportError, RuntimeError, OSError):
        pass
    found = ctypes.util.find_library("espeak-ng")
    if found:
        return found, None
    raise SynthesisUnavailableError(
        "no espeak-ng library: `pip install espeakng-loader` (bundles the library and its voices) or "
        "`sudo apt-get install libespeak-ng1 espeak-ng-data`"
    )


class _Engine:
    """The process's one espeak-ng instance (loaded on first use)."""

    def __init__(self) -> None:
        path, data = _library_and_data()
        try:
            self.lib = ctypes.CDLL(path)
        except OSError as err:
            raise SynthesisUnavailableError(f"cannot load espeak-ng from {path}: {err}") from err
        lib = self.lib
        lib.espeak_Initialize.restype = ctypes.c_int
        lib.espeak_Initialize.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_char_p, ctypes.c_int]
        lib.espeak_SetSynthCallback.argtypes = [_CALLBACK]
        lib.espeak_SetVoiceByName.argtypes = [ctypes.c_char_p]
        lib.espeak_SetVoiceByName.restype = ctypes.c_int
        lib.espeak_SetParameter.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int]
        lib.espeak_GetParameter.argtypes = [ctypes.c_int, ctypes.c_int]
        lib.espeak_GetParameter.restype = ctypes.c_int
        lib.espeak_Synth.argtypes = [
            ctypes.c_void_p,
            ctypes.c_size_t,
            ctypes.c_uint,
            ctypes.c_int,
            ctypes.c_uint,
            ctypes.c_uint,
            ctypes.POINTER(ctypes.c_uint),
            ctypes.c_void_p,
        ]
        lib.espeak_Synth.restype = ctypes.c_int
        lib.espeak_Synchronize.restype = ctypes.c_int
        rate = lib.espeak_Initialize(
            _AUDIO_OUTPUT_SYNCHRONOUS,
            200,
            data.encode() if data else None,
            _INITIALIZE_PHONEME_EVENTS | _INITIALIZE_DONT_EXIT,
        )
        if rate <= 0:
            raise SynthesisUnavailableError(f"espeak-ng failed to initialise (data {data or 'system'})")
        self.sample_rate_hz = int(rate)
        self._chunks: list[NDArray[np.int16]] = []
        self._events: list[tuple[int, int, str, int, int]] = []
        self._written = 0
        self._callback = _CALLBACK(self._on_audio)  # keep a reference: the C side holds the pointer
        lib.espeak_SetSynthCallback(self._callback)
        self.lock = threading.Lock()
        self._voice = ""

    def _on_audio(self, wav: ctypes._Pointer, n_samples: int, events: ctypes._Pointer) -> int:  # type: ignore[type-arg]
        start = self._written
        if n_samples > 0 and wav:
            chunk = np.ctypeslib.as_array(wav, shape=(n_samples,)).astype(np.int16, copy=True)
            self._chunks.append(chunk)
            self._written += n_samples
        i = 0
        while True:
            ev = events[i]
            if ev.type == _EVENT_LIST_TERMINATED:
                break
            if ev.type == _EVENT_PHONEME:
                name = bytes(ev.id.string).split(b"\0", 1)[0].decode("utf-8", "replace")
                self._events.append((ev.type, ev.audio_position, name, ev.text_position, start))
            elif ev.type == _EVENT_WORD:
                self._events.append((ev.type, ev.audio_position, "", ev.text_position, ev.length))
            i += 1
        return 0

    def synthesize(self, text: str, voice: str, rate_wpm: int | None, pitch: int | None) -> Synthesis:
        with self.lock:
            if voice != self._voice:
                if self.lib.espeak_SetVoiceByName(voice.encode()) != 0:
                    raise SpeechError(f"voice {voice!r}: espeak-ng has no such voice (try 'en', 'en-us', 'de')")
                self._voice = voice
            # espeak-ng keeps a rate or pitch once set: None means its default again, not the last caller's
            for param, value in ((_PARAM_RATE, rate_wpm), (_PARAM_PITCH, pitch)):
                default = self.lib.espeak_GetParameter(param, 0)  # current=0: the default value
                self.lib.espeak_SetParameter(param, default if value is None else value, 0)
            self._chunks, self._events, self._written = [], [], 0
            data = text.encode("utf-8") + b"\0"
            buf = ctypes.create_string_buffer(data)
            err = self.lib.espeak_Synth(buf, len(data), 0, _POS_CHARACTER, 0, _CHARS_UTF8 | _ENDPAUSE, None, None)
            if err != 0:
                raise SpeechError(f"espeak-ng synthesis failed (error {err}) for text {text[:40]!r}")
            self.lib.espeak_Synchronize()
            samples = np.concatenate(self._chunks) if self._chunks else np.zeros(0, np.int16)
            events = list(self._events)
        rate = self.sample_rate_hz
        phonemes = []
        words = []
        for kind, pos_ms, name, text_pos, extra in events:
            if kind == _EVENT_PHONEME:
                sample = int(round(pos_ms * rate / 1000.0))
                phonemes.append(PhonemeEvent(name, pos_ms / 1000.0, sample))
            else:
                words.append(WordEvent(pos_ms / 1000.0, max(text_pos - 1, 0), extra))
        phonemes.sort(key=lambda p: p.t_s)
        return Synthesis(text, voice, samples, rate, tuple(phonemes), tuple(words))


_ENGINE: _Engine | None = None
_ENGINE_LOCK = threading.Lock()


def _engine() -> _Engine:
    global _ENGINE
    with _ENGINE_LOCK:
        if _ENGINE is None:
            _ENGINE = _Engine()
        return _ENGINE


def synthesize(text: str, *, voice: str = "en-us", rate_wpm: int | None = None, pitch: int | None = None) -> Synthesis:
    """Speak ``text`` with espeak-ng: audio plus phoneme and word events in the audio's clock."""
    if not isinstance(text, str) or not text.strip():
        raise SpeechError(f"text: expected a non-empty string, got {text!r:.60}")
    if len(text) > MAX_TEXT_CHARS:
        raise SpeechError(f"text: at most {MAX_TEXT_CHARS} characters, got {len(text)}")
    if (
        not isinstance(voice, str)
        or not voice
        or len(voice) > 40
        or not voice.replace("-", "").replace("+", "").isalnum()
    ):
        raise SpeechError(f"voice: expected an espeak-ng voice name such as 'en-us', got {voice!r:.60}")
    for name, value, (lo, hi) in (("rate_wpm", rate_wpm, RATE_WPM_RANGE), ("pitch", pitch, PITCH_RANGE)):
        if value is not None and (isinstance(value, bool) or not isinstance(value, int) or not lo <= value <= hi):
            raise SpeechError(f"{name}: expected an integer within {lo}..{hi}, got {value!r}")
    return _engine().synthesize(text, voice, rate_wpm, pitch)
