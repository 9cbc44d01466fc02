"""Speech: a head that talks. Phonemes with times (espeak-ng synthesis events, forced alignment of recorded
speech, or a causal loudness envelope of any audio) -> visemes -> mouth AUs on a ``speech`` track.

- :mod:`.espeak`    text -> audio + phoneme events (libespeak-ng's synthesis callback; exact by construction)
- :mod:`.align`     recorded speech + transcript -> phonemes with times (pocketsphinx forced alignment)
- :mod:`.envelope`  any audio -> causal jaw/lip opening and a rough mouth class (live-capable)
- :mod:`.visemes`   phoneme -> viseme table (15 visemes, Oculus/MPEG-4 style) and viseme -> AU recipes
- :mod:`.plan`      timed visemes -> a lip-sync clip (coarticulation, bilabial closure, lead, loudness)
- :mod:`.script_out` a planned clip as an editable TOML timeline script that ``servoface play`` reads
"""
