"""The study reproduced.

`statements` (its statements and the scorecard), `checks` (one criterion per statement),
`runs` (its runs, their metrics, the coupling scan), `floquet` (case 8's period doubling).
"""
