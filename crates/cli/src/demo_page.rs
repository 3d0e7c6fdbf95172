//! `index.html` of `evigrid demo`: one page a person opens to see what the demo did, the
//! animation, the legend, the final views, the tables of `report.md` and the plots.
//!
//! Self-contained: every picture and link is relative to the output folder, the style is inline,
//! and nothing is fetched from a network (no script, no web font), so the folder can be copied
//! or zipped and opened anywhere.

use std::fmt::Write as _;
use std::fs;
use std::io::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use eval::EvalReport;
use evigrid::Label;
use output::{ClassColours, OUTLINE, PATH, class_name, write_atomic};

use output::run_figures::OSM_ATTRIBUTION;

/// Writes `out/index.html` from `out/report.md` (read back: its tables are the evaluation's)
/// and the pictures the demo wrote beside it.
pub(crate) fn write_index(out: &Path, report: &EvalReport, colours: &ClassColours) -> Result<()> {
    let md_path = out.join("report.md");
    let markdown = fs::read_to_string(&md_path)
        .with_context(|| format!("cannot read {}", md_path.display()))?;
    let page = page(report, colours, &markdown);
    write_atomic(&out.join("index.html"), |f| f.write_all(page.as_bytes()))?;
    Ok(())
}

/// The page's HTML.
fn page(report: &EvalReport, colours: &ClassColours, markdown: &str) -> String {
    let mut h = String::new();
    let frames = report.frames_per_seed;
    let seconds = frames as f64 * report.frame_period_s;
    h.push_str(
        "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n\
         <title>evigrid demo</title>\n<style>\n\
         body { font-family: sans-serif; max-width: 1600px; margin: 1em auto; padding: 0 1em; \
         color: #111; }\n\
         img { max-width: 100%; height: auto; border: 1px solid #ccc; }\n\
         a.third { flex: 1 1 30%; min-width: 300px; }\n\
         a.third img { width: 100%; }\n\
         img.cells { image-rendering: pixelated; width: 100%; max-width: 1296px; }\n\
         table { border-collapse: collapse; margin: 0.5em 0 1em; }\n\
         td, th { border: 1px solid #bbb; padding: 2px 8px; text-align: right; }\n\
         th { background: #eee; }\n\
         td:first-child, th:first-child { text-align: left; }\n\
         .swatch { display: inline-block; width: 1.1em; height: 1.1em; \
         border: 1px solid #000; vertical-align: middle; margin-right: 0.5em; }\n\
         .row { display: flex; flex-wrap: wrap; gap: 1em; align-items: flex-start; }\n\
         pre { background: #f4f4f4; padding: 0.5em; overflow-x: auto; }\n\
         </style>\n</head>\n<body>\n",
    );
    let _ = writeln!(
        h,
        "<h1>evigrid demo</h1>\n<p>A simulated drive of {frames} frames ({seconds:.0} s) with \
         traffic over a real map of central Helsinki. Left: the simulator's truth; right: what \
         the method <code>evigrid</code> (the paper's evidential grid fused with the map, with \
         motion evidence) decided. Files: \
         <a href=\"report.md\">report.md</a>, <a href=\"metrics.json\">metrics.json</a>, \
         the Foxglove recording <a href=\"run.mcap\">run.mcap</a>.</p>"
    );

    h.push_str("<h2>Animation</h2>\n<div class=\"row\">\n");
    h.push_str(
        "<figure><img class=\"cells\" src=\"decision.gif\" alt=\"truth beside decision, \
         animated over the drive\"><figcaption>Truth (left) beside decision (right), one \
         pixel per 0.5 m cell, north up, 10 frames per second.</figcaption></figure>\n",
    );
    h.push_str(&legend_html(colours));
    h.push_str("</div>\n");

    h.push_str("<h2>Plots</h2>\n<div class=\"row\">\n");
    for v in &report.variants {
        let name = escape(v.variant.name());
        let _ = writeln!(
            h,
            "<img src=\"confusion-{name}.png\" alt=\"confusion matrix of {name}\">"
        );
    }
    h.push_str("<img src=\"per-class-iou.png\" alt=\"IoU per class and variant\">\n</div>\n");

    h.push_str(
        "<h2>After the last frame</h2>\n<p>Enlarged, with the map's outlines (white), the \
         ego's path, a scale bar and a north arrow; click one for full size.</p>\n\
         <div class=\"row\">\n",
    );
    for (file, alt) in [
        ("decision.png", "truth beside the final decision map"),
        ("pignistic.png", "truth beside the final pignistic view"),
        ("trace.png", "truth beside the trace of moving objects"),
    ] {
        let _ = writeln!(
            h,
            "<a class=\"third\" href=\"{file}\"><img src=\"{file}\" alt=\"{alt}\"></a>"
        );
    }

    h.push_str("</div>\n");
    h.push_str("<h2>Report</h2>\n");
    h.push_str(&markdown_to_html(markdown));
    let _ = writeln!(h, "<p><small>{}.</small></p>", escape(OSM_ATTRIBUTION));
    h.push_str("</body>\n</html>\n");
    h
}

/// The legend: a swatch per class, the truth's edge band, and the overlay's lines.
fn legend_html(colours: &ClassColours) -> String {
    let mut h =
        String::from("<div>\n<h3>Legend</h3>\n<ul style=\"list-style: none; padding: 0\">\n");
    let swatch = |rgb: [u8; 3]| {
        format!(
            "<span class=\"swatch\" style=\"background: rgb({}, {}, {})\"></span>",
            rgb[0], rgb[1], rgb[2]
        )
    };
    for label in [
        Label::F,
        Label::I,
        Label::U,
        Label::S,
        Label::M,
        Label::Unknown,
        Label::O,
        Label::Edge,
    ] {
        let _ = writeln!(
            h,
            "<li>{}{}</li>",
            swatch(colours.of(label)),
            escape(class_name(label))
        );
    }
    let _ = writeln!(
        h,
        "<li>{}map outline (buildings, roads), in the PNGs</li>",
        swatch(OUTLINE.0)
    );
    let _ = writeln!(h, "<li>{}ego path, in the PNGs</li>", swatch(PATH.0));
    h.push_str(
        "</ul>\n<p>Colours after Okabe &amp; Ito, told apart with red-green colour \
         blindness.</p>\n</div>\n",
    );
    h
}

/// `&`, `<`, `>` and `"` escaped.
fn escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Escapes `text` and turns `` `code` `` spans into `<code>` and `**bold**` into `<strong>`
/// (outside code).
fn inline(text: &str) -> String {
    let mut out = String::new();
    for (k, part) in text.split('`').enumerate() {
        if k % 2 == 1 {
            let _ = write!(out, "<code>{}</code>", escape(part));
        } else {
            for (j, piece) in escape(part).split("**").enumerate() {
                if j % 2 == 1 {
                    let _ = write!(out, "<strong>{piece}</strong>");
                } else {
                    out.push_str(piece);
                }
            }
        }
    }
    out
}

/// The subset of Markdown `report.md` uses: headings, pipe tables, bullet lists, fenced code
/// and paragraphs. Headings go down two levels (they sit under the page's "Report" `h2`).
fn markdown_to_html(markdown: &str) -> String {
    #[derive(PartialEq)]
    enum Block {
        None,
        Paragraph,
        Table,
        List,
        Code,
    }
    let close = |h: &mut String, block: &Block| match block {
        Block::Paragraph => h.push_str("</p>\n"),
        Block::Table => h.push_str("</table>\n"),
        Block::List => h.push_str("</ul>\n"),
        Block::Code => h.push_str("</pre>\n"),
        Block::None => {}
    };
    let mut h = String::new();
    let mut block = Block::None;
    let mut header_row = false;
    for line in markdown.lines() {
        let trimmed = line.trim();
        if block == Block::Code {
            if trimmed.starts_with("```") {
                close(&mut h, &block);
                block = Block::None;
            } else {
                let _ = writeln!(h, "{}", escape(line));
            }
            continue;
        }
        if trimmed.starts_with("```") {
            close(&mut h, &block);
            h.push_str("<pre>");
            block = Block::Code;
        } else if trimmed.is_empty() {
            close(&mut h, &block);
            block = Block::None;
        } else if let Some(level) = heading_level(trimmed) {
            close(&mut h, &block);
            block = Block::None;
            let text = trimmed[level..].trim();
            let tag = (level + 2).min(6);
            let _ = writeln!(h, "<h{tag}>{}</h{tag}>", inline(text));
        } else if trimmed.starts_with('|') {
            if block != Block::Table {
                close(&mut h, &block);
                h.push_str("<table>\n");
                block = Block::Table;
                header_row = true;
            }
            let cells: Vec<&str> = trimmed
                .trim_matches('|')
                .split('|')
                .map(str::trim)
                .collect();
            if cells
                .iter()
                .all(|c| !c.is_empty() && c.chars().all(|ch| "-: ".contains(ch)))
            {
                continue; // the |---| separator
            }
            let tag = if header_row { "th" } else { "td" };
            header_row = false;
            h.push_str("<tr>");
            for c in cells {
                let _ = write!(h, "<{tag}>{}</{tag}>", inline(c));
            }
            h.push_str("</tr>\n");
        } else if let Some(item) = trimmed.strip_prefix("- ") {
            if block != Block::List {
                close(&mut h, &block);
                h.push_str("<ul>\n");
                block = Block::List;
            }
            let _ = writeln!(h, "<li>{}</li>", inline(item));
        } else {
            if block != Block::Paragraph {
                close(&mut h, &block);
                h.push_str("<p>");
                block = Block::Paragraph;
            } else {
                h.push(' ');
            }
            h.push_str(&inline(trimmed));
        }
    }
    close(&mut h, &block);
    h
}

/// The number of leading `#` of an ATX heading (`# Title`), if the line is one.
fn heading_level(line: &str) -> Option<usize> {
    let level = line.chars().take_while(|&c| c == '#').count();
    (1..=6)
        .contains(&level)
        .then_some(level)
        .filter(|&l| line[l..].starts_with(' '))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markdown_tables_headings_lists_and_code_become_html() {
        let md = "# evigrid demo\n\nCommand (wall <1 s):\n\n```sh\nevigrid demo --out a&b\n```\n\n\
                  ## Scores\n\n| variant | IoU M |\n|---|---|\n| kurdej2013 | 0.050 |\n\
                  | no-map | 0.039 |\n\n- `x.png`: a picture\n- two\n\nplain\n**bold** text\n";
        let h = markdown_to_html(md);
        assert!(h.contains("<h3>evigrid demo</h3>"), "{h}");
        assert!(h.contains("<p>Command (wall &lt;1 s):</p>"), "{h}");
        assert!(h.contains("<pre>evigrid demo --out a&amp;b\n</pre>"), "{h}");
        assert!(h.contains("<h4>Scores</h4>"), "{h}");
        assert!(
            h.contains(
                "<table>\n<tr><th>variant</th><th>IoU M</th></tr>\n\
                 <tr><td>kurdej2013</td><td>0.050</td></tr>\n\
                 <tr><td>no-map</td><td>0.039</td></tr>\n</table>"
            ),
            "{h}"
        );
        assert!(
            h.contains("<ul>\n<li><code>x.png</code>: a picture</li>\n<li>two</li>\n</ul>"),
            "{h}"
        );
        assert!(h.contains("<p>plain <strong>bold</strong> text</p>"), "{h}");
        assert_eq!(heading_level("#hashtag"), None);
        assert_eq!(heading_level("### x"), Some(3));
    }

    #[test]
    fn legend_names_every_class_in_its_colour() {
        let h = legend_html(&output::COLOURS);
        assert!(
            h.contains("rgb(213, 94, 0)") && h.contains("M  moving object"),
            "{h}"
        );
        assert!(
            h.contains("rgb(240, 228, 66)") && h.contains("S  stopped object"),
            "{h}"
        );
        assert!(h.contains("ego path"));
        // Every code the page's pictures can show, the truth's edge band included, has an
        // entry in the one palette's colour (code 6, O, was missing).
        for label in Label::ALL {
            let [r, g, b] = output::COLOURS.of(label);
            let entry = format!(
                "<li><span class=\"swatch\" style=\"background: rgb({r}, {g}, {b})\"></span>{}</li>",
                escape(class_name(label))
            );
            assert!(h.contains(&entry), "{label:?}: {h}");
        }
        assert_eq!(
            escape("<a href=\"x\">&</a>"),
            "&lt;a href=&quot;x&quot;&gt;&amp;&lt;/a&gt;"
        );
    }
}
