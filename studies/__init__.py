"""One-off studies with their own runners (docs/results/): the top layer beside ``pipelines``, on the
library's public names only. Run each as a script: ``python studies/<name>.py --help``."""
