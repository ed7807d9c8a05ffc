"""PlatformIO platform class of the local offline AVR platform (no packages to fetch)."""

from platformio.public import PlatformBase


class RgbdavrlocalPlatform(PlatformBase):
    pass
