"""Tools behind command-line verbs that the core does not import (the work-precision study of
``rodnet bench``)."""
