//! Columns of a Parquet file held in memory (a zip member or a small file), read by name
//! with the row and the column named in every error.

use arrow_array::cast::AsArray;
use arrow_array::types::{
    Float32Type, Float64Type, Int8Type, Int16Type, Int32Type, Int64Type, UInt8Type, UInt16Type,
    UInt32Type, UInt64Type,
};
use arrow_array::{Array, RecordBatch};
use arrow_schema::{DataType, TimeUnit};
use bytes::Bytes;
use parquet::arrow::arrow_reader::{ArrowReaderOptions, ParquetRecordBatchReaderBuilder};

use crate::error::{ImportError, Result};

/// A Parquet table in memory.
#[derive(Debug)]
pub struct Table {
    location: String,
    columns: Vec<String>,
    batches: Vec<RecordBatch>,
    rows: usize,
}

impl Table {
    /// Reads a whole Parquet file from `bytes`; `location` names it in errors (a path, or
    /// `archive.zip: member`).
    pub fn read(location: &str, bytes: Vec<u8>) -> Result<Self> {
        let not_parquet = |e: parquet::errors::ParquetError| {
            ImportError::data(location, format!("not a readable Parquet file: {e}"))
        };
        // The embedded Arrow schema is ignored so that pandas categoricals decode as plain
        // strings (as in fogline-envelope's readers).
        let builder = ParquetRecordBatchReaderBuilder::try_new_with_options(
            Bytes::from(bytes),
            ArrowReaderOptions::new().with_skip_arrow_metadata(true),
        )
        .map_err(not_parquet)?;
        let columns = builder
            .schema()
            .fields()
            .iter()
            .map(|f| f.name().clone())
            .collect();
        let reader = builder
            .with_batch_size(65_536)
            .build()
            .map_err(not_parquet)?;
        let mut batches = Vec::new();
        let mut rows = 0;
        for batch in reader {
            let batch = batch.map_err(|e| {
                ImportError::data(location, format!("not a readable Parquet file: {e}"))
            })?;
            rows += batch.num_rows();
            batches.push(batch);
        }
        Ok(Self {
            location: location.to_string(),
            columns,
            batches,
            rows,
        })
    }

    /// Where the table came from.
    pub fn location(&self) -> &str {
        &self.location
    }

    /// The number of rows.
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Whether the table has column `name`.
    pub fn has(&self, name: &str) -> bool {
        self.columns.iter().any(|c| c == name)
    }

    fn index(&self, name: &str) -> Result<usize> {
        self.columns.iter().position(|c| c == name).ok_or_else(|| {
            ImportError::data(
                &self.location,
                format!(
                    "no column `{name}` (the columns are: {})",
                    if self.columns.is_empty() {
                        "none".to_string()
                    } else {
                        self.columns.join(", ")
                    }
                ),
            )
        })
    }

    /// Visits every cell of column `name` with its 1-based row number.
    fn each<T>(
        &self,
        name: &str,
        expected: &str,
        mut cell: impl FnMut(&dyn Array, usize) -> Option<std::result::Result<T, String>>,
    ) -> Result<Vec<T>> {
        let k = self.index(name)?;
        let mut out = Vec::with_capacity(self.rows);
        let mut row = 0u64;
        for batch in &self.batches {
            let a = batch.column(k).as_ref();
            for i in 0..a.len() {
                row += 1;
                if a.is_null(i) {
                    return Err(ImportError::cell(
                        &self.location,
                        row,
                        name,
                        format!("empty (null); expected {expected}"),
                    ));
                }
                match cell(a, i) {
                    Some(Ok(v)) => out.push(v),
                    Some(Err(detail)) => {
                        return Err(ImportError::cell(&self.location, row, name, detail));
                    }
                    None => {
                        return Err(ImportError::cell(
                            &self.location,
                            row,
                            name,
                            format!("a column of type {}; expected {expected}", a.data_type()),
                        ));
                    }
                }
            }
        }
        Ok(out)
    }

    /// Column `name` as integers (any integer type, or a timestamp in microseconds).
    pub fn i64_column(&self, name: &str) -> Result<Vec<i64>> {
        self.each(name, "integers", |a, i| {
            let v: i64 = match a.data_type() {
                DataType::Int64 => a.as_primitive::<Int64Type>().value(i),
                DataType::Int32 => i64::from(a.as_primitive::<Int32Type>().value(i)),
                DataType::Int16 => i64::from(a.as_primitive::<Int16Type>().value(i)),
                DataType::Int8 => i64::from(a.as_primitive::<Int8Type>().value(i)),
                DataType::UInt32 => i64::from(a.as_primitive::<UInt32Type>().value(i)),
                DataType::UInt16 => i64::from(a.as_primitive::<UInt16Type>().value(i)),
                DataType::UInt8 => i64::from(a.as_primitive::<UInt8Type>().value(i)),
                DataType::UInt64 => {
                    let v = a.as_primitive::<UInt64Type>().value(i);
                    match i64::try_from(v) {
                        Ok(v) => v,
                        Err(_) => return Some(Err(format!("{v} is too large"))),
                    }
                }
                DataType::Timestamp(TimeUnit::Microsecond, _) => a
                    .as_primitive::<arrow_array::types::TimestampMicrosecondType>()
                    .value(i),
                _ => return None,
            };
            Some(Ok(v))
        })
    }

    /// Column `name` as finite numbers (floats or integers).
    pub fn f64_column(&self, name: &str) -> Result<Vec<f64>> {
        self.each(name, "finite numbers", |a, i| {
            let v = match a.data_type() {
                DataType::Float64 => a.as_primitive::<Float64Type>().value(i),
                DataType::Float32 => f64::from(a.as_primitive::<Float32Type>().value(i)),
                DataType::Int64 => a.as_primitive::<Int64Type>().value(i) as f64,
                DataType::Int32 => f64::from(a.as_primitive::<Int32Type>().value(i)),
                _ => return None,
            };
            Some(if v.is_finite() {
                Ok(v)
            } else {
                Err(format!("{v} is not a finite number"))
            })
        })
    }

    /// Column `name` as text.
    pub fn str_column(&self, name: &str) -> Result<Vec<String>> {
        self.each(name, "text", |a, i| {
            let s = match a.data_type() {
                DataType::Utf8 => a.as_string::<i32>().value(i),
                DataType::LargeUtf8 => a.as_string::<i64>().value(i),
                DataType::Utf8View => a.as_string_view().value(i),
                _ => return None,
            };
            Some(Ok(s.to_string()))
        })
    }

    /// Column `name` as booleans, or `None` when the table has no such column.
    pub fn opt_bool_column(&self, name: &str) -> Result<Option<Vec<bool>>> {
        if !self.has(name) {
            return Ok(None);
        }
        self.each(name, "booleans", |a, i| match a.data_type() {
            DataType::Boolean => Some(Ok(a.as_boolean().value(i))),
            _ => None,
        })
        .map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::parquet_bytes as parquet;
    use arrow_array::{ArrayRef, Float64Array, Int64Array, StringArray};
    use std::sync::Arc;

    #[test]
    fn columns_by_name_with_rows_in_errors() {
        let bytes = parquet(vec![
            (
                "timestamp",
                Arc::new(Int64Array::from(vec![1, 2, 3])) as ArrayRef,
            ),
            (
                "x",
                Arc::new(Float64Array::from(vec![Some(0.5), None, Some(1.0)])),
            ),
            ("name", Arc::new(StringArray::from(vec!["a", "b", "c"]))),
        ]);
        let t = Table::read("t.parquet", bytes).unwrap();
        assert_eq!(t.rows(), 3);
        assert_eq!(t.i64_column("timestamp").unwrap(), vec![1, 2, 3]);
        assert_eq!(t.str_column("name").unwrap(), vec!["a", "b", "c"]);
        let e = t.f64_column("x").unwrap_err().to_string();
        assert!(
            e.contains("row 2") && e.contains("`x`") && e.contains("null"),
            "{e}"
        );
        let e = t.f64_column("qw").unwrap_err().to_string();
        assert!(
            e.contains("no column `qw`") && e.contains("timestamp, x, name"),
            "{e}"
        );
        let e = t.i64_column("name").unwrap_err().to_string();
        assert!(
            e.contains("row 1") && e.contains("expected integers"),
            "{e}"
        );
        assert_eq!(t.opt_bool_column("valid").unwrap(), None);
        let e = Table::read("bad.parquet", b"PAR1 not really".to_vec())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("bad.parquet: not a readable Parquet file"),
            "{e}"
        );
    }
}
