"""From a model to the kernels' tables: the one place that turns a System's descriptions into the
flat arrays the compiled equations read (``layout``)."""
