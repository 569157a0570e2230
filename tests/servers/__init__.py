"""Throwaway servers from Debian's packages for the tests marked ``servers``."""
