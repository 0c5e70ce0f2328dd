"""The live view (`lubrig view`) without ROS.

`display` (display rates and decimation), `layouts` (Foxglove and PlotJuggler layouts),
`access` (what a Foxglove client may do).
"""
