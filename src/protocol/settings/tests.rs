//! Host tests of the settings table and the record.
