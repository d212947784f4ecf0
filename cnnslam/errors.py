"""Exceptions of the SLAM package. One base class; subclasses where callers need to tell cases apart."""


class CnnSlamError(ValueError):
    """Base class for every error raised by ``cnnslam`` (bad configuration, bad input images, missing weights)."""
