"""Image conditioning: training renders, encoder feature cache, image-conditioned transformer
training, loading and evaluation (docs/imaging.md). Heavy modules load on import of a submodule."""
