"""The study reproduced: `lubrig paper` (docs/report.md, docs/study.md).

`statements` (its statements and the scorecard), `checks` (one criterion per statement),
`runs` (its runs, their metrics, the coupling-scan table), `floquet` (case 8's period doubling),
`scan` (the coupling scan on the sweep engine), `figures` (the scan's figures), `reproduce` (runs,
measures and scores every reading, writes the page), `page` (the page), `numbers` (the numbers its
mechanism texts quote), `floquet_page` (its account of case 8's period doubling).
"""
