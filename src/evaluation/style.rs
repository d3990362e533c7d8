//! One look per method in every plot and report: a colour, a line pattern and a marker,
//! keyed by the method's name, so that a method is drawn alike in every plot of every
//! report (`eval`, `table1`, `live`) whichever methods share the plot. `adaptive`, the
//! method the project is about, gets the first style (the palette's blue, a solid line,
//! discs); then the other methods of the default evaluation, so each of them has a
//! colour no other one of them has; then the rest.

use plotters::style::RGBColor;

use super::DEFAULT_METHODS;
use crate::methods::MethodKind;

/// Line colours: Tableau 10, chosen to be told apart, also by most colour-blind readers
/// when combined with [`DASHES`] and [`MARKERS`].
const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

/// Line patterns, `(dash, gap)` in pixels, `(0, 0)` solid. Three, prime to the
/// palette's ten: no two of the first 30 styles share both colour and pattern.
const DASHES: [(u32, u32); 3] = [(0, 0), (9, 5), (2, 4)];

/// A mark drawn on a line every few points, so that lines of one colour or crossing
/// lines can be told apart, in grey print too.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Marker {
    /// A filled disc.
    Circle,
    /// An upward triangle.
    Triangle,
    /// A filled square.
    Square,
    /// A diagonal cross.
    Cross,
}

/// Four marks: with the ten colours and three patterns, the first 60 styles differ in
/// at least one of the three from every other.
const MARKERS: [Marker; 4] = [
    Marker::Circle,
    Marker::Triangle,
    Marker::Square,
    Marker::Cross,
];

/// How one series is drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Style {
    /// Line and marker colour.
    pub colour: RGBColor,
    /// `(dash, gap)` in pixels; `(0, 0)` is solid.
    pub dash: (u32, u32),
    /// The mark on the line.
    pub marker: Marker,
    /// Where in the cycle of points the marks start, so that the marks of different
    /// methods do not all fall on the same refreshes.
    pub phase: usize,
}

impl Style {
    /// The colour as CSS (`#rrggbb`), for the HTML around the plots.
    pub fn css(&self) -> String {
        let RGBColor(r, g, b) = self.colour;
        format!("#{r:02x}{g:02x}{b:02x}")
    }
}

/// Style number `k`.
fn nth(k: usize) -> Style {
    Style {
        colour: PALETTE[k % PALETTE.len()],
        dash: DASHES[k % DASHES.len()],
        marker: MARKERS[k % MARKERS.len()],
        phase: k,
    }
}

/// A method's place in the order styles are handed out in: `adaptive`, the other
/// default methods, then every other method in registry order.
fn rank(method: MethodKind) -> usize {
    let defaults = DEFAULT_METHODS
        .iter()
        .filter(|m| **m != MethodKind::Adaptive);
    let others = MethodKind::ALL
        .iter()
        .filter(|m| !DEFAULT_METHODS.contains(m));
    std::iter::once(&MethodKind::Adaptive)
        .chain(defaults)
        .chain(others)
        .position(|m| *m == method)
        .expect("every method is in the registry")
}

/// The style of the method named `name` (an old name too); `None` for a name no method
/// has.
pub fn of_method(name: &str) -> Option<Style> {
    MethodKind::parse(name).ok().map(|m| nth(rank(m)))
}

/// The style of series `i` of a plot, named `name`: its method's, else one after every
/// method's (a series that is no method still differs from each).
pub fn of_series(name: &str, i: usize) -> Style {
    of_method(name).unwrap_or_else(|| nth(MethodKind::ALL.len() + i))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_method_has_its_own_style_and_the_defaults_their_own_colour() {
        let styles: Vec<Style> = MethodKind::ALL
            .iter()
            .map(|m| of_method(m.name()).unwrap())
            .collect();
        for (i, a) in styles.iter().enumerate() {
            for b in &styles[i + 1..] {
                assert!((a.colour, a.dash, a.marker) != (b.colour, b.dash, b.marker));
            }
        }
        let colours: Vec<RGBColor> = DEFAULT_METHODS
            .iter()
            .map(|m| of_method(m.name()).unwrap().colour)
            .collect();
        for (i, c) in colours.iter().enumerate() {
            assert!(!colours[i + 1..].contains(c), "{}", DEFAULT_METHODS[i]);
        }
        // Keyed by the name, not the plot: the real-time pipeline's methods (and old
        // names) look as the evaluation's do.
        assert_eq!(of_method("framed"), of_method("framed-full"));
        assert_eq!(of_series("taa", 0), of_series("taa", 5));
        assert!(of_method("bogus").is_none());
        assert_eq!(of_method("adaptive").unwrap().css().len(), 7);
    }
}
