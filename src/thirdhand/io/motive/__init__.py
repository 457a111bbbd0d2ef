"""OptiTrack Motive CSV exports: rigid bodies (and labelled markers) in, 1.23-style exports out.

A Motive export (format versions 1.2x, written by Motive 1.10 to 3.x) looks like::

    Format Version,1.23,Take Name,T1,...,Export Frame Rate,120.000000,...,Length Units,Meters,...
    <blank line>
    ,Type,Rigid Body,Rigid Body,...,Marker,...
    ,Name,seat,seat,...,seat:Marker1,...
    ,ID,1,1,...
    ,Parent,...                                  (newer versions only)
    ,,Rotation,Rotation,Rotation,Rotation,Position,Position,Position,Mean Marker Error,...
    Frame,Time (Seconds),X,Y,Z,W,X,Y,Z,,...
    0,0.000000,0.001,...

Rows come and go between versions (format 1.21 has no ``Type``/``Name``/``ID``
labels, some exports add a ``TimeCode`` column after the time), so header rows are
found by their label, or by their content when unlabelled, never by position.
Blank cells mean "not tracked". The numeric block is handed to Arrow's
multi-threaded CSV parser; the header is parsed in Python.

The writer appends one key to the first line, ``Up Axis``, which Motive does not
write; readers that parse the first line by position are not affected.

Modules
-------
:mod:`~thirdhand.io.motive.reader` (``read``) parses the header with
:mod:`~thirdhand.io.motive.header` (``sniff``), finds each body's columns with
:mod:`~thirdhand.io.motive.columns` and reads the numbers with
:mod:`~thirdhand.io.motive.block`; :mod:`~thirdhand.io.motive.writer` holds ``write``.
"""

from thirdhand.io.motive.constants import ASSET_TYPES, LENGTH_UNITS
from thirdhand.io.motive.header import sniff
from thirdhand.io.motive.reader import read, sidecar_path
from thirdhand.io.motive.writer import write

__all__ = ["ASSET_TYPES", "LENGTH_UNITS", "read", "sidecar_path", "sniff", "write"]
