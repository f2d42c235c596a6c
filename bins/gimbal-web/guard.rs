//! Failed sign-ins, limited per account and address (issue 49): before a
//! password is checked, the attempt must be allowed for that account from
//! that address; only failures count, so a right password never spends
//! anything.
//!
//! - **Per account and address**: each (account, address) pair may fail
//!   [`PAIR_BURST`] times, then once every [`PAIR_EVERY`]; past that, its
//!   attempts are answered 429 without a check. Another address's
//!   attempts at the same account, and the same address's at another
//!   account, are not touched: one wrong guess every 2 s behind one proxy
//!   address kept the administrator's right password at 429 when the
//!   attempts of an address were counted whoever they were for. An IPv6
//!   address counts as its /64 (one host picks any address of it). A name
//!   that is no configured account is one account ("unknown").
//! - **An account under attack**: each configured account also counts its
//!   failures from every address, [`ACCOUNT_BURST`] then one a second;
//!   past that the account is under attack for [`ATTACK_HOLD`] after its
//!   last failure over it. Meanwhile an address that failed at that
//!   account within [`ATTACK_HOLD`] is refused until that long after its
//!   own last failure, while an address that has not is still checked:
//!   the right password from elsewhere signs in (decided: an account is
//!   never locked for everyone; a distributed guesser gets one try per
//!   address per [`ATTACK_HOLD`] instead of a burst and a rate each).
//! - **Bounded, never full**: at most [`PAIRS`] pairs are remembered; one
//!   not remembered is always checked, and a new failure past the bound
//!   forgets the pair that failed least recently. A flood of addresses
//!   thus costs at most that table and never refuses an address it has
//!   not seen (1,024 addresses at 600 tries a second filled the table of
//!   attempts, and every address not seen before was refused).

use std::collections::HashMap;
use std::net::IpAddr;
use std::time::Duration;

use sagebrush_service::rate::TokenBucket;
use tokio::time::Instant;

/// Failures a pair may have at once, then one per [`PAIR_EVERY`].
pub const PAIR_BURST: f64 = 10.0;
pub const PAIR_EVERY: Duration = Duration::from_secs(2);
/// Failures an account may have from all addresses at once, then one a second.
pub const ACCOUNT_BURST: f64 = 100.0;
const ACCOUNT_PER_S: f64 = 1.0;
/// How long an account stays under attack, and an address that failed at
/// it then waits.
pub const ATTACK_HOLD: Duration = Duration::from_secs(60);
/// Pairs remembered at most.
pub const PAIRS: usize = 4096;

/// Where attempts come from: an IPv4 address, or an IPv6 address's /64.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct Net(IpAddr);

impl Net {
    fn of(ip: IpAddr) -> Self {
        match ip.to_canonical() {
            IpAddr::V6(v6) => Self(IpAddr::V6((u128::from(v6) & (!0u128 << 64)).into())),
            v4 => Self(v4),
        }
    }
}

/// One pair's failures.
#[derive(Debug, Clone, Copy)]
struct Pair {
    budget: TokenBucket,
    last: Instant,
}

/// One configured account's failures from every address.
#[derive(Debug, Clone, Copy)]
struct Account {
    budget: TokenBucket,
    attacked: Option<Instant>,
}

#[derive(Debug)]
pub struct Guard {
    /// Per configured account (by its index); a name that is none is `accounts.len()`.
    accounts: Vec<Account>,
    pairs: HashMap<(usize, Net), Pair>,
    capacity: usize,
}

impl Guard {
    /// For `accounts` configured accounts, remembering at most `capacity` pairs.
    pub fn new(accounts: usize, capacity: usize, now: Instant) -> Self {
        let account = Account {
            budget: TokenBucket::new(ACCOUNT_PER_S, ACCOUNT_BURST, now),
            attacked: None,
        };
        Self {
            accounts: vec![account; accounts],
            pairs: HashMap::new(),
            capacity: capacity.max(1),
        }
    }

    fn key(&self, account: Option<usize>, ip: IpAddr) -> (usize, Net) {
        let slot = account
            .filter(|a| *a < self.accounts.len())
            .unwrap_or(self.accounts.len());
        (slot, Net::of(ip))
    }

    fn under_attack(&self, slot: usize, now: Instant) -> bool {
        self.accounts
            .get(slot)
            .and_then(|a| a.attacked)
            .is_some_and(|t| now.saturating_duration_since(t) < ATTACK_HOLD)
    }

    /// Whether an attempt at `account` (its index; `None`: no such name)
    /// from `ip` may be checked now.
    pub fn may_try(&self, account: Option<usize>, ip: IpAddr, now: Instant) -> bool {
        let key = self.key(account, ip);
        let Some(pair) = self.pairs.get(&key) else {
            return true;
        };
        if self.under_attack(key.0, now) && now.saturating_duration_since(pair.last) < ATTACK_HOLD {
            return false;
        }
        let mut budget = pair.budget;
        budget.take(now)
    }

    /// A failed attempt at `account` from `ip`.
    pub fn failed(&mut self, account: Option<usize>, ip: IpAddr, now: Instant) {
        let key = self.key(account, ip);
        if let Some(a) = self.accounts.get_mut(key.0) {
            if !a.budget.take(now) {
                a.attacked = Some(now);
            }
        }
        if !self.pairs.contains_key(&key) && self.pairs.len() >= self.capacity {
            let oldest = self.pairs.iter().min_by_key(|(_, p)| p.last).map(|(k, _)| *k);
            if let Some(k) = oldest {
                self.pairs.remove(&k);
            }
        }
        let pair = self.pairs.entry(key).or_insert(Pair {
            budget: TokenBucket::new(1.0 / PAIR_EVERY.as_secs_f64(), PAIR_BURST, now),
            last: now,
        });
        pair.budget.take(now);
        pair.last = now;
    }

    /// A right password for `account` from `ip`: that pair's failures are forgotten.
    pub fn succeeded(&mut self, account: Option<usize>, ip: IpAddr) {
        let key = self.key(account, ip);
        self.pairs.remove(&key);
    }

    /// Pairs remembered now.
    #[cfg(test)]
    fn len(&self) -> usize {
        self.pairs.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ADMIN: Option<usize> = Some(0);

    fn ip(s: &str) -> IpAddr {
        s.parse().unwrap()
    }

    #[test]
    fn a_pairs_failures_refuse_only_that_pair() {
        let t = Instant::now();
        let mut g = Guard::new(2, 64, t);
        let (attacker, admin) = (ip("192.0.2.66"), ip("192.0.2.7"));
        let tried = (0..50).filter(|_| {
            let ok = g.may_try(ADMIN, attacker, t);
            if ok {
                g.failed(ADMIN, attacker, t);
            }
            ok
        });
        assert_eq!(tried.count(), 10, "the burst");
        assert!(!g.may_try(ADMIN, attacker, t));
        assert!(g.may_try(ADMIN, admin, t), "another address at the same account");
        assert!(g.may_try(Some(1), attacker, t), "the same address at another account");
        assert!(g.may_try(ADMIN, attacker, t + PAIR_EVERY), "one more every PAIR_EVERY");
        g.failed(ADMIN, admin, t);
        g.succeeded(ADMIN, admin);
        assert_eq!(g.len(), 1, "a right password forgets its pair's failures");
    }

    #[test]
    fn an_account_under_attack_still_checks_an_address_that_has_not_failed() {
        let t = Instant::now();
        let mut g = Guard::new(1, PAIRS, t);
        for i in 0..200u32 {
            g.failed(ADMIN, ip(&format!("10.0.{}.{}", i / 256, i % 256)), t);
        }
        assert!(g.under_attack(0, t));
        assert!(
            !g.may_try(ADMIN, ip("10.0.0.1"), t),
            "an attacker's address, with budget left, waits"
        );
        assert!(
            g.may_try(ADMIN, ip("192.0.2.7"), t),
            "the administrator elsewhere is checked"
        );
        assert!(g.may_try(ADMIN, ip("10.0.0.1"), t + ATTACK_HOLD));
        assert!(
            g.may_try(None, ip("10.0.0.1"), t),
            "no such name: not the account's attack"
        );
    }

    #[test]
    fn the_table_is_bounded_and_forgets_the_least_recently_failed() {
        let t = Instant::now();
        let mut g = Guard::new(1, 8, t);
        let flood = |i: u32| ip(&format!("10.1.{}.{}", i / 256, i % 256));
        for i in 0..10_000u32 {
            g.failed(None, flood(i), t + Duration::from_millis(u64::from(i)));
        }
        assert_eq!(g.len(), 8);
        assert!(
            g.may_try(ADMIN, ip("192.0.2.7"), t),
            "a new address is never refused for the table"
        );
        assert!(g.may_try(None, flood(0), t), "forgotten");
    }

    #[test]
    fn an_ipv6_address_counts_as_its_64() {
        let t = Instant::now();
        let mut g = Guard::new(1, 64, t);
        for i in 0..10u16 {
            g.failed(ADMIN, ip(&format!("2001:db8:1:2::{i:x}")), t);
        }
        assert!(!g.may_try(ADMIN, ip("2001:db8:1:2::ffff"), t));
        assert!(g.may_try(ADMIN, ip("2001:db8:1:3::1"), t));
    }
}
