// Every number of the decoder's options by name ("growth.faintest"), so that one can be set for a
// run without a build (`cellsim decode-sweep --decoder-option NAME=VALUE`): what each number does
// is measured by setting it and sweeping (docs/decoding.md, "What each number does"). The
// switches (which steps run) have their own flags.
#pragma once

#include <string>
#include <vector>

#include "servo/vision/spot_decoder.hpp"

namespace vision {

// the names set_decoder_option knows, in the options structs' order
std::vector<std::string> decoder_option_names();

// Sets one number from "NAME=VALUE". Throws std::invalid_argument, naming the assignment, when
// NAME is unknown, VALUE is not a finite number in the range NAME takes ([0, 1e9]; the
// segmentation's window [1, 255], its 8-bit levels and noise factor [0, 255]), or a count's VALUE is not whole.
void set_decoder_option(DecoderOptions& options, const std::string& assignment);

}  // namespace vision
