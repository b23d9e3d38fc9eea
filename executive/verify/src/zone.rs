//! Clock zones: difference-bound matrices (the representation of timed automata's clock
//! constraints, as in UPPAAL) over the clocks of the timed exploration — mission time, each
//! running activity, each armed timer, each battery reading's age. All clocks advance together,
//! so bounds on their differences stay exact while time passes; this is what intervals per
//! clock lose (a timer armed when a reading was taken fires exactly one period after it).
//!
//! Entry `(i, j)` bounds `x_i − x_j ≤ m[i][j]` (non-strict; clock 0 is the constant zero).

/// A zone over `n − 1` clocks.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Zone {
    n: usize,
    m: Vec<f64>,
}

const INF: f64 = f64::INFINITY;

impl Zone {
    /// Only clock 0 (zero).
    pub(crate) fn new() -> Zone {
        Zone { n: 1, m: vec![0.0] }
    }

    fn at(&self, i: usize, j: usize) -> f64 {
        self.m[i * self.n + j]
    }

    fn set(&mut self, i: usize, j: usize, v: f64) {
        self.m[i * self.n + j] = v;
    }

    /// Adds a clock that reads 0 now; returns its index.
    pub(crate) fn add(&mut self) -> usize {
        let n = self.n;
        let mut m = vec![0.0; (n + 1) * (n + 1)];
        for i in 0..n {
            for j in 0..n {
                m[i * (n + 1) + j] = self.at(i, j);
            }
        }
        // x_new = x_0: the same bounds as clock 0.
        for j in 0..n {
            m[n * (n + 1) + j] = self.at(0, j);
            m[j * (n + 1) + n] = self.at(j, 0);
        }
        m[n * (n + 1) + n] = 0.0;
        self.n = n + 1;
        self.m = m;
        n
    }

    /// Removes clock `k` (its constraints are projected away; the zone stays closed).
    pub(crate) fn remove(&mut self, k: usize) {
        let n = self.n;
        let keep: Vec<usize> = (0..n).filter(|&i| i != k).collect();
        self.reorder(&keep);
    }

    /// The zone over the clocks `order` (old indices; 0 first) in that order.
    pub(crate) fn reorder(&mut self, order: &[usize]) {
        let n = order.len();
        let mut m = vec![0.0; n * n];
        for (a, &i) in order.iter().enumerate() {
            for (b, &j) in order.iter().enumerate() {
                m[a * n + b] = self.at(i, j);
            }
        }
        self.n = n;
        self.m = m;
    }

    /// Tightens every bound (Floyd–Warshall); `false` if the zone is empty.
    pub(crate) fn close(&mut self) -> bool {
        let n = self.n;
        for k in 0..n {
            for i in 0..n {
                let ik = self.at(i, k);
                if ik == INF {
                    continue;
                }
                for j in 0..n {
                    let v = ik + self.at(k, j);
                    if v < self.at(i, j) {
                        self.set(i, j, v);
                    }
                }
            }
        }
        (0..n).all(|i| self.at(i, i) >= -1e-6)
    }

    /// Lets any amount of time pass.
    pub(crate) fn up(&mut self) {
        for i in 1..self.n {
            self.set(i, 0, INF);
        }
    }

    /// `x_k ≤ c`.
    pub(crate) fn at_most(&mut self, k: usize, c: f64) {
        if c < self.at(k, 0) {
            self.set(k, 0, c);
        }
    }

    /// `x_k ≥ c`.
    pub(crate) fn at_least(&mut self, k: usize, c: f64) {
        if -c < self.at(0, k) {
            self.set(0, k, -c);
        }
    }

    /// Forgets how far clock `k` is beyond `c` (extrapolation: every bound past `c` is dropped,
    /// which only adds valuations); the zone is closed again.
    pub(crate) fn forget(&mut self, k: usize, c: f64) {
        for j in 0..self.n {
            if j != k && self.at(k, j) > c {
                self.set(k, j, INF);
            }
            if j != k && self.at(j, k) < -c {
                self.set(j, k, -c);
            }
        }
        self.close();
    }

    /// The least and greatest value of clock `k`.
    pub(crate) fn bounds(&self, k: usize) -> (f64, f64) {
        ((-self.at(0, k)).max(0.0), self.at(k, 0))
    }

    /// The smallest zone holding both (the same clocks in the same order).
    pub(crate) fn join(&mut self, o: &Zone) {
        for (a, b) in self.m.iter_mut().zip(&o.m) {
            *a = a.max(*b);
        }
    }

    /// Whether every valuation of `o` is in this zone (both closed, the same clocks).
    pub(crate) fn includes(&self, o: &Zone) -> bool {
        self.n == o.n && self.m.iter().zip(&o.m).all(|(a, b)| *a >= *b - 1e-6)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clocks_advance_together_and_keep_their_differences() {
        let mut z = Zone::new();
        let reading = z.add();
        z.up();
        z.at_most(reading, 30.0);
        assert!(z.close());
        // A timer armed 10 to 30 after the reading.
        let timer = z.add();
        z.up();
        z.at_most(timer, 60.0);
        z.at_least(timer, 60.0);
        assert!(z.close());
        assert_eq!(z.bounds(timer), (60.0, 60.0));
        // The reading is 60 to 90 old when the timer fires: exact, not 60 to infinity.
        assert_eq!(z.bounds(reading), (60.0, 90.0));
        z.remove(timer);
        let mut other = Zone::new();
        other.add();
        let mut both = z.clone();
        both.join(&other);
        assert!(both.includes(&z) && both.includes(&other) && !z.includes(&other));
        z.at_most(reading, 10.0);
        assert!(!z.close(), "90 ≥ age ≥ 60 and age ≤ 10 is empty");
    }
}
