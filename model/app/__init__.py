"""Application layer: the commands, servers and benches that tie several layers together
(the studio page, the export bench, ...). The top of model/'s layer order: nothing in the
other packages imports it (test/test_core_package.py checks the order)."""
