"""ROS 2 plumbing of artformer: the ``artformer_generator`` node (``generator_node``), the
``request`` demo client, the one-command demo and the node benchmark. No model maths here:
generation is ``model.pipeline``. Importing this package imports nothing heavy."""
