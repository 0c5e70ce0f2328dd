"""What a recording holds and how it plays back.

`accounting` (per-stream sample accounting), `lateness` (realtime timing as recorded),
`replay` (the replay's playback state) and `replay_flow` (its lossless pacing).
"""
