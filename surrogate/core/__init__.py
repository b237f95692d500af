"""The shared infrastructure every part of the package stands on: units and errors, where the shipped
files are, reading inputs and writing outputs (atomically, never over an input), TOML, progress
lines, clean stops on signals, threads and memory, plain-text tables. It imports nothing else of the
package.
"""
