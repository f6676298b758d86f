"""The station view: a local web page that shows a running bench and the lab's records.

`bench serve` starts it. It reads run directories (and the records database) and never
sits in the acquisition path; its one action, a stop request, is Ctrl-C to the bench.
"""
