"""Exceptions of the SLAM package. One base class; subclasses where callers need to tell cases apart."""

from slamcommon.errors import ProjectError


class CnnSlamError(ProjectError):
    """Base class for every error raised by ``cnnslam`` (bad configuration, bad input images, missing weights)."""
