// Numbers in messages: enough significant digits to be read and compared, never "0.000000"
// for a small value (std::to_string's fixed notation).
#pragma once

#include <string>

namespace springfit {

// `value` with `digits` significant digits, %g style: 1.23e-09, 0.5, 1.5e+06, inf, nan.
std::string NumberText(double value, int digits = 3);

}  // namespace springfit
