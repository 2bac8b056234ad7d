-- strata schema 15: whether a marker's sigma is the survey's own statement of its
-- precision (a sigma column in the file, or `import markers --sigma`) or strata's
-- default weight. The layer's verdict judges the control and check figures against
-- what a stated survey can deliver (docs/quality.md, "The survey's yardstick"); a
-- default weight says nothing about the survey. Markers imported before this schema
-- count as not stated: their verdict stays what it was.
ALTER TABLE markers ADD COLUMN sigma_stated INTEGER NOT NULL DEFAULT 0;
