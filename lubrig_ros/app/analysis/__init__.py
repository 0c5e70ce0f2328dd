"""Analysis of a rig's displacement, offline and online.

`policy`: the one wavelet-analysis policy of a run (`analyze_displacement` → `WaveletAnalysis`);
`session`: the analysis node's rules without ROS.
"""
