"""Clients of a running graph: waits on discovery, messages and services without sleeping."""
