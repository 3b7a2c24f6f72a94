"""Writes the Parquet fixtures of this folder with pyarrow (an independent writer: the Rust
`parquet` crate writes no page checksums and, as built for truepos, no GZIP).

    python3 make_fixtures.py      # pyarrow 26.0.1 wrote the committed files

- crc_points.parquet: x_mm, y_mm, z_mm (DOUBLE, required), 5 rows, uncompressed, plain encoding,
  every page with its CRC-32 (write_page_checksum=True). Points on a sphere of radius 10 mm
  centred at (1, 2, 3): x = 11, -9; y = 12, -8; z = 13.
- gzip_points.parquet: the same columns and rows, GZIP pages.
- logical_points.parquet: x_mm DECIMAL(9,3) stored as INT32 (12.345, -0.001, 999999.999),
  y_mm UINT32 (0, 4294967295, 7), z_mm INT8 (-128, 0, 127), Snappy, dictionary pages, CRCs;
  and t DATE (refused by truepos: dates are not plain numbers) in dated_points.parquet.
"""
import datetime
from decimal import Decimal
import pyarrow as pa
import pyarrow.parquet as pq

rows = [(11.0, 2.0, 3.0), (-9.0, 2.0, 3.0), (1.0, 12.0, 3.0), (1.0, -8.0, 3.0), (1.0, 2.0, 13.0)]
schema = pa.schema([pa.field(n, pa.float64(), nullable=False) for n in ("x_mm", "y_mm", "z_mm")])
table = pa.table({n: [r[i] for r in rows] for i, n in enumerate(("x_mm", "y_mm", "z_mm"))}, schema=schema)
pq.write_table(table, "crc_points.parquet", compression="NONE", use_dictionary=False,
               write_page_checksum=True, write_statistics=False, store_schema=False)
pq.write_table(table, "gzip_points.parquet", compression="GZIP", use_dictionary=False,
               write_statistics=False, store_schema=False)

logical = pa.table({
    "x_mm": pa.array([Decimal("12.345"), Decimal("-0.001"), Decimal("999999.999")], pa.decimal128(9, 3)),
    "y_mm": pa.array([0, 4294967295, 7], pa.uint32()),
    "z_mm": pa.array([-128, 0, 127], pa.int8()),
})
pq.write_table(logical, "logical_points.parquet", compression="SNAPPY", write_page_checksum=True,
               store_decimal_as_integer=True, write_statistics=False, store_schema=False)
dated = logical.append_column("t", pa.array([datetime.date(2026, 11, 28)] * 3, pa.date32()))
pq.write_table(dated, "dated_points.parquet", compression="SNAPPY", store_decimal_as_integer=True,
               write_statistics=False, store_schema=False)
# pyarrow's default for decimals: FIXED_LEN_BYTE_ARRAY (truepos refuses it, naming the type).
pq.write_table(logical, "fixed_decimal_points.parquet", compression="SNAPPY",
               write_statistics=False, store_schema=False)
